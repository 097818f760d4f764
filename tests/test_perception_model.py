"""The observation model: the group as deploy's perception would see it, in the engine."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ssbl_pb.env.engine.batched import BatchedApproach
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.params import ConfigError, RobotParams, SocialParams
from ssbl_pb.perception.groups.observation_model import CopyPerception, PerceptionParams, detect

EXACT = PerceptionParams(range_std_m=0.0, range_std_per_m=0.0, bearing_std_deg=0.0, miss_prob=0.0, laser_std_m=0.0,
                         facing_flip_prob=0.0)


def _copy(params: PerceptionParams = EXACT) -> CopyPerception:
    cp = CopyPerception(RobotParams(), SocialParams(), keep=0.8, paper=False, params=params)
    cp.seed(0)
    return cp


def test_range_noise_grows_with_distance_as_configured():
    params = PerceptionParams(range_std_m=0.0, range_std_per_m=0.1, bearing_std_deg=0.0, miss_prob=0.0,
                              laser_reach_m=0.0)  # no lasers: the colour chain
    rng = np.random.default_rng(0)
    xy = np.array([[1.0, 0.0], [0.0, 4.0]])
    seen = np.array([detect(xy, np.ones(2, bool), params, rng)[0] for _ in range(4000)])
    ranges = np.hypot(seen[..., 0], seen[..., 1])
    assert ranges[:, 0].std() == pytest.approx(0.1, rel=0.05) and ranges[:, 1].std() == pytest.approx(0.4, rel=0.05)
    assert np.allclose(np.arctan2(seen[:, 1, 1], seen[:, 1, 0]), math.pi / 2)  # no bearing noise asked for


def test_within_the_lasers_reach_the_range_noise_is_the_lasers_and_beyond_it_the_keypoints():
    params = PerceptionParams(laser_reach_m=3.0, laser_std_m=0.02, range_std_m=0.0, range_std_per_m=0.1,
                              bearing_std_deg=0.0, miss_prob=0.0)
    rng = np.random.default_rng(1)
    xy = np.array([[2.9, 0.0], [0.0, 4.0]])
    seen = np.array([detect(xy, np.ones(2, bool), params, rng)[0] for _ in range(4000)])
    ranges = np.hypot(seen[..., 0], seen[..., 1])
    assert ranges[:, 0].std() == pytest.approx(0.02, rel=0.05) and ranges[:, 1].std() == pytest.approx(0.4, rel=0.05)


def test_the_presets_are_movenets_chain_by_default_and_the_colour_detectors_on_request():
    assert PerceptionParams.of(True) == PerceptionParams() == PerceptionParams.of("movenet")
    movenet, colour = PerceptionParams(), PerceptionParams.of("colour")
    assert movenet.keypoints and movenet.laser_reach_m == 3.0 and movenet.min_visible > colour.min_visible
    assert not colour.keypoints and colour.laser_reach_m == 0.0 and colour.miss_prob == 0.03
    changed = PerceptionParams.of({"preset": "colour", "miss_prob": 0.1})
    assert changed.miss_prob == 0.1 and changed.range_std_per_m == colour.range_std_per_m
    with pytest.raises(ConfigError, match="perception.detector"):
        PerceptionParams.of({"detector": "hog"})
    with pytest.raises(ConfigError, match="'hog': expected false, true, one of"):
        PerceptionParams.of({"preset": "hog"})


def test_movenets_chain_expects_a_person_only_clear_of_the_image_side_as_deploy_keeps_its_boxes():
    colour, movenet = _copy(PerceptionParams.of("colour")), _copy(EXACT)
    assert movenet.tracker.p.edge_margin_m == pytest.approx(0.07 * 1.45)  # BODY_MARGIN x eyes to ankles
    assert movenet.tracker.tracker.params.birth_hits == 3 and movenet.model.robust  # TRACKER_KEYPOINTS, robust centre
    # a person 3.5 m away (beyond the lasers' reach), turned aside until the torso just fits in the image but its
    # margin does not
    bearings = np.radians(np.linspace(0.0, 28.0, 281))
    xy = 3.5 * np.column_stack([np.cos(bearings), np.sin(bearings)])
    whole = colour.detectable(xy)[1] >= 1.0
    clear = movenet.detectable(xy)[1] >= movenet.params.min_visible
    k = int(np.flatnonzero(whole & ~clear)[0])
    assert colour.detectable(xy[k:k + 1])[0][0] and not movenet.detectable(xy[k:k + 1])[0][0]
    assert movenet.detectable(xy[:1])[0][0]  # straight ahead: both


def test_misses_happen_at_the_configured_rate_and_only_the_visible_are_detected():
    params = PerceptionParams(range_std_m=0.0, range_std_per_m=0.0, bearing_std_deg=0.0, miss_prob=0.25)
    rng = np.random.default_rng(1)
    xy = np.array([[2.0, 0.0], [2.0, 1.0]])
    counts = [len(detect(xy, np.array([True, False]), params, rng)[0]) for _ in range(4000)]
    assert np.mean(counts) == pytest.approx(0.75, abs=0.02) and max(counts) == 1


def test_deploy_s_rule_hides_a_member_behind_another_and_outside_the_view():
    tracker = _copy().tracker
    xy = np.array([[2.0, 0.0], [3.2, 0.05], [1.0, 2.0], [3.0, -1.0]])  # front, behind it, 63 deg left, in view
    assert tracker.visible(xy, xy).tolist() == [True, False, False, True]


def test_with_exact_detection_a_group_in_view_is_estimated_where_it_stands():
    cp = _copy()
    members = np.array([[3.0, 0.6], [3.0, -0.6]])  # a pair 3 m ahead, both in view
    pose = np.array([0.0, 0.0, 0.0])
    for _ in range(5):  # the tracker confirms after two hits
        cp.frame(pose, members, 0.1)
    assert cp.group is not None and len(cp.members) == 2
    centre, radius, _, slot = cp.group
    assert centre == pytest.approx([3.0, 0.0], abs=1e-6) and radius == pytest.approx(0.6, abs=1e-6)
    assert slot[0] < 3.0  # the place opens on the robot's side


def test_off_is_the_true_state_and_on_keeps_the_episode_s_start():
    on, off = BatchedApproach(1, "mixed", perception=True), BatchedApproach(1, "mixed")
    for b in (on, off):
        b.seed(0, 7)
        b.reset(0)
    assert np.array_equal(on.pose, off.pose) and np.array_equal(on.pos, off.pos)  # the same start
    assert not np.array_equal(on.observations(), off.observations())  # seen differently
    plain = BatchedApproach(1, "mixed", perception=False)
    plain.seed(0, 7)
    plain.reset(0)
    assert np.array_equal(plain.observations(), off.observations())


def test_the_model_is_seeded_and_deterministic():
    def play(seed: int) -> np.ndarray:
        env = ApproachGroupEnv("mixed", perception={"miss_prob": 0.2})
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(30):
            obs, *_ = env.step(np.array([0.5, 0.0]))
            out.append(obs)
        return np.array(out)

    assert np.array_equal(play(3), play(3)) and not np.array_equal(play(3), play(4))


def test_knowing_too_few_people_the_robot_turns_in_place_whatever_the_policy_asks():
    env = ApproachGroupEnv("default", perception=True)
    env.reset(seed=11)
    sim = env.sim
    sim.perceived.known[0] = False  # as at an episode's start: nobody confirmed yet
    before = sim.pose[0].copy()
    env.step(np.array([1.0, 1.0]))  # full speed asked
    assert np.hypot(*(sim.pose[0, :2] - before[:2])) < 1e-9  # ignored: it searches
    assert sim.pose[0, 2] != before[2]


def test_bad_model_settings_are_named():
    with pytest.raises(ConfigError, match="perception.miss_prob"):
        BatchedApproach(1, perception={"miss_prob": 1.5})
    with pytest.raises(ConfigError, match="perception"):
        BatchedApproach(1, perception="yes")


def test_the_share_of_a_torso_hidden_behind_nearer_people_by_hand():
    from ssbl_pb.perception.groups.observation_model import hidden_share

    # behind a person straight ahead: all of it; a person 0.2 m to the side (bearing atan(0.1) = 0.0997 rad,
    # half-angle atan(0.115) = 0.1145 rad) covers the target's rays (k / 10 - 1) atan(0.23 / 3) from -0.0148 rad:
    # k >= 9, 12 of the 21 across its width
    assert hidden_share(np.array([[3.0, 0.0], [2.0, 0.0]]), 0.23).tolist() == [1.0, 0.0]
    assert hidden_share(np.array([[3.0, 0.0], [2.0, 0.2]]), 0.23)[0] == pytest.approx(12 / 21)
    assert hidden_share(np.array([[3.0, 0.0], [2.9, 0.0]]), 0.23)[0] == 0.0  # not nearer by 0.2 m: beside it


def test_the_search_steps_sideways_after_a_full_turn_with_one_person_known():
    from ssbl_pb.perception.groups.estimate import Member

    cp = _copy()
    cp.members = [Member(1, np.array([2.0, 1.0]), np.zeros(2), np.eye(2))]  # to the left: turn left first
    yaw, acts = 0.0, []
    for _ in range(140):
        aim, act = cp.search(np.array([0.0, 0.0, yaw]), heading_gain=2.0, dt=0.1)
        acts.append(act)
        if not act.any():
            yaw += 0.05  # as the base turns
    first = next(k for k, a in enumerate(acts) if a.any())
    assert first == 126  # 2 pi of 0.05 rad steps
    assert np.allclose(acts[first], [0.0, 0.2]) and sum(a.any() for a in acts) == 140 - 126
    assert aim == pytest.approx([2.0, 1.0])  # facing that person while stepping


def test_facing_is_measured_from_the_front_finely_and_from_behind_coarsely():
    params = dataclasses.replace(EXACT, facing_std_deg=10.0, facing_front_deg=80.0, facing_back_std_deg=30.0)
    rng = np.random.default_rng(2)
    xy = np.array([[2.0, 0.0], [3.0, 0.0], [2.0, 1.0]])
    phi = np.array([0.2, math.pi, 0.0])
    draws = [detect(xy, np.array([True, True, False]), params, rng, phi) for _ in range(3000)]
    facing = np.array([d[1] for d in draws])  # the third is not detected
    err = np.remainder(facing - phi[:2] + math.pi, 2 * math.pi) - math.pi
    assert err.std(axis=0) == pytest.approx(np.radians([10.0, 30.0]), rel=0.05)
    assert draws[0][2].tolist() == pytest.approx(np.radians([10.0, 30.0]).tolist())
    unknown = dataclasses.replace(params, facing_back_std_deg=math.inf)
    _, f, sd = detect(xy[1:2], np.array([True]), unknown, rng, phi[1:2])
    assert np.isnan(f).all() and np.isinf(sd).all()  # from behind, unknown: not measured


def test_a_share_of_facings_comes_out_turned_by_half_a_turn_as_keypoints_mistake_front_for_back():
    params = dataclasses.replace(EXACT, facing_std_deg=1.0, facing_back_std_deg=1.0, facing_flip_prob=0.2)
    rng = np.random.default_rng(3)
    xy, phi = np.array([[2.0, 0.0]]), np.array([0.3])
    facing = np.array([detect(xy, np.array([True]), params, rng, phi)[1][0] for _ in range(4000)])
    flipped = np.abs(np.remainder(facing - phi[0] + math.pi, 2 * math.pi) - math.pi) > math.pi / 2
    assert flipped.mean() == pytest.approx(0.2, abs=0.02)
    with pytest.raises(ConfigError, match="perception.facing_flip_prob"):
        PerceptionParams(facing_flip_prob=1.0)


def test_facing_rays_that_cross_fix_the_centre_and_facing_each_other_do_not():
    from ssbl_pb.perception.groups.facing_centre import facing_centre

    c = np.array([1.0, 2.0])
    members = c + np.array([[0.8, 0.0], [0.0, 0.8], [-0.8, 0.0]])
    towards = np.arctan2(c[1] - members[:, 1], c[0] - members[:, 0])
    assert facing_centre(members, towards, np.full(3, 0.1), reach=1.0) == pytest.approx(c)
    pair = np.array([[0.0, 0.0], [1.2, 0.0]])  # vis-a-vis: facing each other along one line
    assert facing_centre(pair, np.array([0.0, math.pi]), np.full(2, 0.1), reach=1.0) is None
    assert facing_centre(pair, np.array([0.0, np.nan]), np.full(2, 0.1), reach=1.0) is None  # one known
    # side by side, facing the same way (+y) 10 deg inward each: ahead of their midpoint by 0.3 / tan(10 deg),
    # capped at the model's o-space radius
    side = np.array([[-0.3, 0.0], [0.3, 0.0]])
    inward = np.radians([80.0, 100.0])
    assert facing_centre(side, inward, np.full(2, 0.5), reach=5.0) == pytest.approx([0.0, 0.3 / math.tan(
        math.radians(10.0))])
    assert facing_centre(side, inward, np.full(2, 0.5), reach=0.9) == pytest.approx([0.0, 0.9])


def test_with_facing_a_pair_seen_from_behind_is_joined_on_its_far_side():
    cp = _copy(dataclasses.replace(EXACT, facing_std_deg=0.0, facing_back_std_deg=0.0))
    members = np.array([[3.0, 0.4], [3.0, -0.4]])  # side by side 3 m ahead, backs to the robot
    yaw = np.radians([-10.0, 10.0])  # facing away, a little inward: their centre is beyond them (x > 3)
    for _ in range(5):
        cp.frame(np.zeros(3), members, 0.1, yaw)
    centre, _, _, slot = cp.group
    assert centre[0] > 3.5 and slot[0] > 3.0  # not the midpoint (3, 0) nor a place on the robot's side


def test_searching_adds_its_time_to_the_episode_up_to_one_episode_more():
    from ssbl_pb.env.engine import kernels

    b = BatchedApproach(1, "default", perception=True)
    b.seed(0, 11)
    b.reset(0)
    limit = b.room[0, kernels.STEP_LIMIT]
    for _ in range(5):
        b.perceived.known[0] = False  # nobody known: it searches
        b.step(np.zeros((1, 2)))
    assert b.room[0, kernels.STEP_LIMIT] == limit + 5 and b.search_steps[0] == 5
    b.search_steps[0] = b.task.max_steps  # a whole episode searched already: no more
    b.perceived.known[0] = False
    b.step(np.zeros((1, 2)))
    assert b.room[0, kernels.STEP_LIMIT] == limit + 5


def test_the_sidestep_goes_to_the_side_with_room_or_not_at_all():
    from ssbl_pb.perception.groups.estimate import Member

    def full_turn(cp, clearance):
        yaw, act = 0.0, np.zeros(2)
        for _ in range(130):
            _, act = cp.search(np.array([0.0, 0.0, yaw]), heading_gain=2.0, dt=0.1, clearance=clearance)
            if act.any():
                return act
            yaw += 0.05
        return act

    person = [Member(1, np.array([2.0, 1.0]), np.zeros(2), np.eye(2))]  # to the left: it would step left
    for wall_left, wall_right, expect in ((False, False, 0.2), (True, False, -0.2), (True, True, 0.0)):
        cp = _copy()
        cp.members = list(person)

        def clearance(pose, wl=wall_left, wr=wall_right):  # a wall close on the robot's left (+y) / right side
            # (after a full turn the robot at the origin faces +x again: its left is +y)
            return 0.1 if (pose[1] > 0 and wl) or (pose[1] < 0 and wr) else 2.0

        act = full_turn(cp, clearance)
        assert act[1] == pytest.approx(expect), (wall_left, wall_right, act)


def test_a_turn_that_would_swing_a_corner_into_the_wall_is_held():
    b = BatchedApproach(1, "default", perception=True)
    b.seed(0, 3)
    b.reset(0)
    half = b.world_params.room_size[0] / 2
    b.pose[0] = [half - b.robot_params.width / 2 - 0.03, 0.0, math.pi / 2]  # facing along the wall, 3 cm off it
    aim = np.array([[half, 1.0]])  # any turn swings a corner (0.32 m from the centre) past the side's 0.215 m
    held = b._turn_guard(aim)
    assert held[0] == pytest.approx(b.pose[0, :2] + np.array([0.0, 1.0]))  # straight ahead: no turn
    b.pose[0, 0] = half - b.robot_params.width / 2 - 0.15  # 15 cm off: one period's turn keeps 5 cm
    assert np.array_equal(b._turn_guard(aim), aim)


def test_a_torso_cut_by_the_image_side_is_completed_beyond_it():
    from ssbl_pb.deploy.perceive import complete_cut_torsos
    from ssbl_pb.perception.groups.estimate import MIN_VISIBLE, TORSO_HALF, TORSO_HEIGHT

    full = 60.0 * (4.0 * sum(TORSO_HALF) / math.pi) / TORSO_HEIGHT  # a 60 px tall torso is ~45.8 px wide
    boxes = np.array([[100.0, 80, 40, 60, 1], [0.0, 80, 30, 60, 1], [300.0, 80, 20, 60, 1], [0.0, 80, 10, 60, 1]])
    out, keep = complete_cut_torsos(boxes, 320)
    assert keep.tolist() == [True, True, True, False]  # the last shows 10 / 45.8 < MIN_VISIBLE of its width
    assert 10 < MIN_VISIBLE * full < 30
    assert out[0].tolist() == boxes[0].tolist()  # whole: as it was
    assert out[1, 0] + out[1, 2] == pytest.approx(30.0) and out[1, 2] == pytest.approx(full)  # its inner edge kept
    assert out[2, 0] == 300.0 and out[2, 2] == pytest.approx(full)


def test_the_share_of_a_torso_inside_the_image_by_hand():
    from ssbl_pb.perception.camera import sim_camera
    from ssbl_pb.perception.groups.observation_model import image_share

    cam = sim_camera(RobotParams(), 320, 240)
    half = math.radians(RobotParams().camera_hfov_deg) / 2
    edge = (3.0 - cam.centre()[0]) * math.tan(half)  # 3 m ahead of the robot, on the image's left side
    share = image_share(np.array([[3.0, 0.0], [3.0, edge], [3.0, edge + 1.0], [-1.0, 0.0]]), cam, 0.23, 1.14, 6.0)
    assert share[0] == 1.0 and share[2] == 0.0 and share[3] == 0.0
    assert share[1] == pytest.approx(0.5, abs=0.05)  # centred on the side: half of it shows


def _one_known(cp):
    from ssbl_pb.perception.groups.estimate import Member

    cp.members = [Member(1, np.array([2.0, 1.0]), np.zeros(2), np.eye(2))]  # to the left: it would step left


def test_without_room_for_the_whole_sidestep_it_takes_a_shorter_one_across_and_back():
    cp = _copy()
    _one_known(cp)
    across = np.array([-1.0, 2.0]) / math.sqrt(5.0)  # left of the line to the person at (2, 1)

    def clearance(pose):  # furniture 0.45 m to either side of that line, none behind
        return 2.0 if abs(float(pose[:2] @ across)) <= 0.45 else 0.1

    yaw, acts = 0.0, []
    for _ in range(140):
        _, act = cp.search(np.array([0.0, 0.0, yaw]), heading_gain=2.0, dt=0.1, clearance=clearance)
        acts.append(act)
        yaw += 0.0 if act.any() else 0.05
    first = next(k for k, a in enumerate(acts) if a.any())
    # across: 0.8 m (the whole 3 s and 0.2 m braking) and 0.6 m (2 s) both reach the furniture; across and back
    # at 135 deg, 2 s: 0.6 m * sin(135 deg) = 0.42 m across, clear
    assert acts[first] == pytest.approx(0.2 * np.array([math.cos(3 * math.pi / 4), math.sin(3 * math.pi / 4)]))
    assert first == 126 and cp.sidestep_left == 20 - (140 - first)  # a 2 s step under way


def test_sidesteps_repeat_while_one_person_stays_the_only_one_known_then_it_turns_again():
    cp = _copy()
    _one_known(cp)
    yaw, moving = 0.0, []
    for _ in range(126 + 3 * 30 + 20):
        _, act = cp.search(np.array([0.0, 0.0, yaw]), heading_gain=2.0, dt=0.1)
        moving.append(bool(act.any()))
        yaw += 0.0 if act.any() else 0.05
    assert moving[:126] == [False] * 126  # a full turn first
    assert moving[126:216] == [True] * 90  # three 3 s sidesteps in a row (sidestep_repeats)
    assert moving[216:] == [False] * 20  # then it turns again


def test_deploys_search_repeats_its_sidesteps_as_the_observation_model_does():
    from ssbl_pb.deploy.loop import DeployLoop, DeployParams

    loop = DeployLoop.__new__(DeployLoop)  # only the search's state: no robot, camera or policy needed
    loop.p = DeployParams(rate_hz=10.0, sidestep_repeats=2)
    loop.s = type("S", (), {"task": type("T", (), {"heading_gain": 2.0})()})()
    loop._approaching, loop._search_side = False, 0.0
    person, yaw, states = np.array([[2.0, 1.0]]), 0.0, []
    for _ in range(126 + 2 * 30 + 10):
        state, cmd = loop._search(np.array([0.0, 0.0, yaw]), person)
        states.append(state)
        yaw += 0.0 if state == "sidestep" else cmd[2] * 0.1
    first = states.index("sidestep")
    assert first == 126  # a full turn at 0.5 rad/s, 0.05 rad a tick
    assert states[first:first + 60] == ["sidestep"] * 60 and states[first + 60:] == ["search"] * 10


def test_at_its_estimated_place_the_robot_looks_at_a_member_not_seen_lately_as_deploy_does():
    from ssbl_pb.core.task import TaskParams
    from ssbl_pb.perception.groups.looks import CLAIM_HOLD_S, STALL_S
    from ssbl_pb.perception.groups.observation_model import PerceivedGroups

    task = TaskParams()
    groups = PerceivedGroups(1, RobotParams(), SocialParams(), 0.8, False, EXACT)
    cp = groups.copies[0]
    cp.seed(0)
    members = np.array([[3.0, 0.6], [3.0, -0.6]])
    for _ in range(5):  # facing each other: the place opens on the robot's side
        groups.frame(0, np.zeros(3), members, np.array([-math.pi / 2, math.pi / 2]), 0.1)
    centre, _, _, slot = cp.group
    assert slot[0] < 3.0
    left = next(k for k, m in enumerate(cp.members) if m.pos[1] > 0)
    cp.looks.seen_at[cp.members[left].id] = -10.0  # not seen for a long while
    d = centre - slot
    at_place = np.array([slot[0], slot[1], math.atan2(d[1], d[0])])  # standing at it, facing the centre
    looks = []
    for _ in range(int(CLAIM_HOLD_S * 10) + 2):
        cp.t += 0.1
        looks.append(cp.look(at_place, 0.0, task))
    assert looks[:int(CLAIM_HOLD_S * 10)] == [None] * int(CLAIM_HOLD_S * 10)  # the rule holds a second first
    assert looks[-1] == left
    # the engine turns it in place toward that member, at most at the search's turn rate
    aim, act, looking = groups.steer(at_place[None], task.heading_gain, 0.1, None, np.zeros(1), task)
    assert looking.tolist() == [True] and act[0].tolist() == [0.0, 0.0]
    turn = math.remainder(math.atan2(aim[0, 1] - at_place[1], aim[0, 0] - at_place[0]) - at_place[2], 2 * math.pi)
    assert turn == pytest.approx(EXACT.search_turn / task.heading_gain)  # to the left, capped
    # moving, or without the robot's speed: the policy drives
    cp.looks = type(cp.looks)(EXACT.confirm_s, seen_at=dict(cp.looks.seen_at))
    assert all(cp.look(at_place, 0.2, task) is None for _ in range(20))
    assert groups.steer(at_place[None], task.heading_gain, 0.1)[2].tolist() == [False]
    # standing 1 m short of its place, it looks after STALL_S
    back = at_place - np.array([math.cos(at_place[2]), math.sin(at_place[2]), 0.0])
    stalled = []
    for _ in range(int(STALL_S * 10) + 2):
        cp.t += 0.1
        stalled.append(cp.look(back, 0.0, task))
    assert stalled[0] is None and stalled[-1] == left


def test_the_engine_lets_the_policy_drive_while_no_look_is_due():
    env = ApproachGroupEnv("default", perception=True)
    env.reset(seed=11)
    sim = env.sim
    for _ in range(200):  # find the group first (a full search turn: 126 steps)
        env.step(np.array([0.0, 0.0]))
        if sim.perceived.known[0]:
            break
    assert sim.perceived.known[0]
    before = sim.pose[0].copy()
    env.step(np.array([1.0, 0.0]))
    assert np.hypot(*(sim.pose[0, :2] - before[:2])) > 0.01  # moving toward the group: no look


def test_robust_facing_centre_weighs_rays_against_the_centroid_and_discounts_a_ray_that_misses():
    from scipy.optimize import brentq

    from ssbl_pb.perception.groups.facing_centre import CENTROID_STD_M, facing_centre, robust_facing_centre

    # two rays from (-1, 0) and (1, 0) meet at (0, 2); a third from (0, 3) points down the y axis (no pull in y);
    # the centroid is (0, 1). By symmetry x = 0; y balances the two rays (normal distance |2 - y| / sqrt(5), std
    # d * 0.1 with d = sqrt(1 + y^2)) against the centroid (std CENTROID_STD_M): a fixed point solved by hand
    members = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, 3.0]])
    facing = np.array([math.atan2(2.0, 1.0), math.atan2(2.0, -1.0), -math.pi / 2])
    std = np.full(3, 0.1)

    def balance(y: float) -> float:
        w = 1.0 / ((1.0 + y * y) * 0.01)
        return 2.0 * w * (y - 2.0) / 5.0 + (y - 1.0) / CENTROID_STD_M ** 2

    y = brentq(balance, 1.0, 2.0)
    assert robust_facing_centre(members, facing, std) == pytest.approx([0.0, y], abs=1e-5)
    assert 1.3 < y < 1.7  # between the rays' crossing and the centroid
    assert robust_facing_centre(members[:2], facing[:2], std[:2]) is None  # a pair: facing_centre's case
    assert robust_facing_centre(members, np.array([facing[0], np.nan, np.nan]), std) is None  # one known

    # four members around (0, 0) facing it within 5 deg, one of them turned 80 deg (a keypoint facing gone wrong):
    # the plain crossing follows the wrong ray; the robust one discounts it
    rng = np.random.default_rng(3)
    angles = np.radians([0.0, 90.0, 180.0, 270.0])
    members = 0.8 * np.column_stack([np.cos(angles), np.sin(angles)])
    facing = angles + math.pi + np.radians(rng.uniform(-5.0, 5.0, 4))
    facing[1] += math.radians(80.0)
    std = np.full(4, math.radians(15.0))
    plain = facing_centre(members, facing, std, reach=1.0)
    robust = robust_facing_centre(members, facing, std)
    assert plain is not None and np.hypot(*plain) > 0.2
    assert np.hypot(*robust) < 0.05


def test_within_the_lasers_reach_a_person_the_image_cuts_is_found_without_a_facing_as_a_laser_places_them():
    movenet = _copy(dataclasses.replace(EXACT, partial_std_m=0.0))
    bearings = np.radians(np.linspace(0.0, 40.0, 401))
    for dist, placed in ((2.0, True), (3.5, False)):  # within the lasers' 3 m, and beyond
        xy = dist * np.column_stack([np.cos(bearings), np.sin(bearings)])
        can, share, cut = movenet.detectable(xy)
        between = (share >= EXACT.cut_share) & (share < EXACT.min_visible)
        assert between.any()
        assert (can[between] == placed).all() and (cut[between] == placed).all(), dist
        assert not can[share < EXACT.cut_share].any() and not cut[share >= EXACT.min_visible].any()
    side = xy[np.flatnonzero(between)[0]] * 2.0 / 3.5  # 2 m away, cut by the image's side
    for _ in range(4):  # the tracker confirms a track on its third hit
        movenet.frame(np.zeros(3), np.array([[2.0, 0.0], side]), 0.1,
                      yaw=np.array([math.pi, math.atan2(side[1], side[0]) + math.pi]))  # both facing the robot
    ahead, cut_one = sorted(movenet.members, key=lambda m: m.pos[1])
    assert ahead.facing is not None and cut_one.facing is None
    assert cut_one.pos == pytest.approx(side, abs=1e-3)
    assert _copy(PerceptionParams.of("colour")).params.cut_share == 0  # the colour chain completes cut torsos
