"""From tracked people to the policy's group: circle, free slot, the joining model and the memory of people out of
view, held against the simulator's own group (core.humans)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.agents.trained import policy_groups
from ssbl_pb.core.humans import Group
from ssbl_pb.core.layouts import free_layout, paper_layout, slot_keep
from ssbl_pb.core.task import TaskParams
from ssbl_pb.params import RobotParams, SocialParams
from ssbl_pb.perception.camera import sim_camera
from ssbl_pb.perception.groups.estimate import (
    KEYPOINT_GROUP,
    GroupModel,
    GroupParams,
    GroupTracker,
    group_circle,
)
from ssbl_pb.perception.tracking.tracker import TrackerParams

SOCIAL = SocialParams()


def test_three_or_more_members_centre_on_their_circle_in_the_paper_model_else_on_their_centroid():
    centre = np.array([1.0, -2.0])
    angles = np.array([0.3, 2.0, 4.0, 5.0])
    pts = centre + 1.3 * np.column_stack([np.cos(angles), np.sin(angles)])
    c, r = group_circle(pts, np.array([5.0, 5.0]), SOCIAL, paper=True)
    assert c == pytest.approx(centre) and r == pytest.approx(1.3)
    c, r = group_circle(pts, np.array([5.0, 5.0]), SOCIAL)  # real groups: the centroid (layouts.real_layout)
    assert c == pytest.approx(pts.mean(axis=0)) and r == pytest.approx(np.hypot(*(pts - c).T).mean())


def test_a_pair_is_centred_on_its_midpoint_or_in_the_paper_model_on_the_robot_side_of_its_chord():
    a, b = np.array([-0.8, 0.0]), np.array([0.8, 0.0])  # 1.6 m apart, the paper model's radius is 1.0 m
    c, r = group_circle(np.array([a, b]), np.array([0.0, -3.0]), SOCIAL)
    assert c == pytest.approx([0.0, 0.0]) and r == pytest.approx(0.8)  # real pairs: symmetric about the centre
    c, r = group_circle(np.array([a, b]), np.array([0.0, -3.0]), SOCIAL, paper=True)
    assert r == 1.0 and c == pytest.approx([0.0, -0.6])  # sqrt(1 - 0.8^2) toward the robot
    c, r = group_circle(np.array([[-1.2, 0.0], [1.2, 0.0]]), np.array([0.0, 3.0]), SOCIAL, paper=True)
    assert c == pytest.approx([0, 0]) and r == pytest.approx(1.2)  # wider than the model: the midpoint


def test_slot_and_joining_match_the_simulated_group():
    keep = slot_keep(SOCIAL, RobotParams().reach, TaskParams().intimate_zone, TaskParams().route_margin)
    for paper, formation, n in ((True, "l_shape", 3), (True, "circular", 4), (False, "circular", 4),
                                (False, "vis_a_vis", 2)):
        lay = paper_layout(formation, n, SOCIAL, 0.7) if paper else free_layout(
            paper_layout(formation, n, SOCIAL, 0.7).offsets * 0.6)  # a tighter, real-sized group
        g = Group(SOCIAL, np.array([0.5, 0.5]), lay, keep)
        model = GroupModel(SOCIAL, keep, paper, smoothing=1.0)
        far, near = np.array([4.0, -1.0]), g.free_slot(np.array([4.0, -1.0])) * 1.1
        centre, radius, w, slot = model.update(g.pos, far)
        assert centre == pytest.approx(g.centre0) and w == 0.0, formation
        assert slot == pytest.approx(g.free_slot(far)) and radius == pytest.approx(g.radius), formation
        g.update_centre(near)  # inside the joining zone the measured centre is held, the model joins the robot
        centre, radius, w, slot = model.update(g.pos + 0.02, near)
        # (the members moved 2 cm: the place, hence the joining distance, moves by about that much; a pair stays
        # symmetric about its centre, so a calibrated pair's centre is their midpoint, moved with them)
        held = g.centre + (0.02 if n == 2 and not paper else 0.0)
        assert w == pytest.approx(g.join_weight, abs=0.05) and w > 0 and centre == pytest.approx(held), formation
        assert radius == pytest.approx(g.radius, abs=0.01), formation


def _tracker() -> GroupTracker:
    cam = sim_camera(RobotParams(), 320, 240)
    return GroupTracker(cam, TrackerParams(dt=0.1, birth_hits=2, meas_std=0.05), social=SOCIAL)


def test_a_person_leaving_the_view_is_remembered_and_forgotten_once_their_place_is_clear():
    gt = _tracker()
    person = np.array([[3.0, 0.0]])
    for _ in range(3):
        members = gt.update(person, 0.1, np.zeros(3))
    assert len(members) == 1 and members[0].seen
    # the robot turns 90 deg left: the person is now out of view (to its right), so nothing is detected
    for _ in range(30):
        members = gt.update(np.zeros((0, 2)), 0.1, np.array([0.0, 0.0, math.pi / 2]))
    assert len(members) == 1 and not members[0].seen
    assert members[0].pos == pytest.approx([3.0, 0.0], abs=0.1)  # still where it was, in the odometry frame
    # turning back, its place is in clear view but nobody is there: forgotten after forget_frames
    for _ in range(gt.p.forget_frames):
        members = gt.update(np.zeros((0, 2)), 0.1, np.zeros(3))
    assert members == []


def test_a_hidden_person_is_not_forgotten():
    gt = _tracker()
    near, far = np.array([2.0, 0.0]), np.array([4.0, 0.05])
    for _ in range(3):
        gt.update(np.array([near, far]), 0.1, np.zeros(3))
    for _ in range(20):  # the far one stands right behind the near one: hidden, not gone
        members = gt.update(np.array([near]), 0.1, np.zeros(3))
    assert len(members) == 2


def test_a_person_cut_by_the_side_of_the_image_is_not_expected_to_be_detected():
    gt = _tracker()
    at = lambda rng, deg: rng * np.array([[math.cos(math.radians(deg)), math.sin(math.radians(deg))]])  # noqa: E731
    # 1.1 m away and 19 deg off the axis (a member beside the robot at its place): the body's centre is in the
    # image, its side is not, and perceive drops boxes cut by the image's side
    assert not gt.visible(at(1.1, 19.0), np.zeros((0, 2)))[0]
    assert not gt.visible(at(1.1, -19.0), np.zeros((0, 2)))[0]
    assert gt.visible(at(3.0, 10.0), np.zeros((0, 2)))[0] and gt.visible(at(1.1, 0.0), np.zeros((0, 2)))[0]
    assert not gt.visible(at(7.0, 0.0), np.zeros((0, 2)))[0]  # beyond max_range_m


def test_with_an_edge_margin_a_body_near_the_side_of_the_image_is_not_expected_to_be_detected():
    # perceive drops MoveNet's boxes within BODY_MARGIN of the image's side (0.1 m at the person): the memory must not
    # expect a detection there either, or it forgets a member standing 1.5 m away, 14 deg off the axis, in 5 frames
    cam = sim_camera(RobotParams(), 640, 480)
    at = lambda rng, deg: rng * np.array([[math.cos(math.radians(deg)), math.sin(math.radians(deg))]])  # noqa: E731
    plain, edged = GroupTracker(cam), GroupTracker(cam, params=GroupParams(edge_margin_m=0.1))
    assert plain.visible(at(1.5, 14.0), np.zeros((0, 2)))[0] and not edged.visible(at(1.5, 14.0), np.zeros((0, 2)))[0]
    assert edged.visible(at(1.5, 12.0), np.zeros((0, 2)))[0]


def test_members_out_of_view_stay_where_last_estimated_while_the_robot_joins():
    # a real-sized pair 3 m ahead, walking slowly; the robot sees it, then stands at its place looking away for
    # 10 s: once the tracker stops coasting them, the members it remembers stand where it last estimated them,
    # not drifting on by their last velocity
    gt = _tracker()
    model = gt.model
    g = Group(SOCIAL, np.array([3.0, 0.0]), free_layout(np.array([[0.0, -0.45], [0.0, 0.45]])), model.keep)

    def frame(detections: np.ndarray, pose: np.ndarray) -> list:
        members = sorted(gt.update(detections, 0.1, pose), key=lambda m: m.pos[1])
        if len(members) == 2:  # the tracker confirms a track on its second hit
            model.update(np.array([m.pos for m in members]), pose[:2], np.array([m.rest for m in members]))
        return members

    pose = np.zeros(3)
    for k in range(5):
        members = frame(g.pos + np.array([0.02 * k, 0.0]), pose)  # drifting 0.2 m/s along x
    assert len(members) == 2 and model.weight == 0.0
    assert all(np.hypot(*m.vel) > 0.05 for m in members)  # the tracker measured the drift
    slot = g.free_slot(pose[:2])
    away = np.array([*slot, math.pi])  # at the slot, facing away from the group: nobody in view
    for k in range(100):
        g.step(slot, 0.1)
        members = frame(np.zeros((0, 2)), away)
        if k == 20:  # the tracker has given up coasting them: remembered, they stay put
            last = np.array([m.pos for m in members])
    assert len(members) == 2 and not any(m.seen for m in members)
    assert np.array([m.pos for m in members]) == pytest.approx(last, abs=1e-12)
    assert all(not m.vel.any() for m in members)


def test_the_group_model_defaults_to_the_one_the_policy_was_trained_on(tmp_path):
    assert policy_groups("vector") == "calibrated" and policy_groups("sffm") == "calibrated"
    (tmp_path / "model.zip").write_bytes(b"")
    (tmp_path / "config.yaml").write_text("obs_mode: vector\nenv:\n  groups: paper\n")
    assert policy_groups(str(tmp_path)) == "paper"
    (tmp_path / "config.yaml").write_text("obs_mode: vector\nenv: {}\n")
    assert policy_groups(str(tmp_path)) == "calibrated"  # the env's default


# -- one id per person ---------------------------------------------------------------------------------
def test_a_person_who_comes_back_into_view_keeps_their_id():
    # the tracker drops a person out of view after max_misses; the group remembers them, and the track the
    # tracker starts when they come back is that remembered member (it had a new id, and lost its rest position)
    gt = _tracker()
    person = np.array([[3.0, 0.0]])
    for _ in range(3):
        gt.update(person, 0.1, np.zeros(3))
    for _ in range(30):  # turned 90 deg left: out of view, longer than the tracker keeps a track
        members = gt.update(np.zeros((0, 2)), 0.1, np.array([0.0, 0.0, math.pi / 2]))
    assert [m.id for m in members] == [1] and not members[0].seen and gt.tracker.tracks == []
    rest = members[0].rest.copy()
    for _ in range(3):
        members = gt.update(person + 0.05, 0.1, np.zeros(3))
    assert [m.id for m in members] == [1] and members[0].seen
    assert members[0].rest == pytest.approx(rest + 0.05)  # not joining: where they stand now is their rest
    for _ in range(20):
        members = gt.update(person + 0.05, 0.1, np.zeros(3))
    assert [m.id for m in members] == [1]


def test_a_track_born_beside_a_coasting_one_takes_its_id():
    # a person undetected for a few frames reappears outside the tracker's gate: the new track is that person,
    # not a second one beside a coasting copy (which the tracker would report for max_misses frames)
    gt = _tracker()
    for _ in range(5):
        gt.update(np.array([[3.0, 0.0]]), 0.1, np.zeros(3))
    members = gt.update(np.zeros((0, 2)), 0.1, np.zeros(3))
    assert [m.id for m in members] == [1] and not members[0].seen
    for _ in range(3):  # 0.5 m off: outside the tracker's gate, inside same_person_m
        members = gt.update(np.array([[3.0, 0.5]]), 0.1, np.zeros(3))
        assert [m.id for m in members] == [1]
    assert members[0].seen and members[0].pos == pytest.approx([3.0, 0.5], abs=0.05)
    assert len(gt.tracker.tracks) == 1 and gt.alias == {2: 1}
    # a second person farther than same_person_m from everyone is someone else
    for _ in range(3):
        members = gt.update(np.array([[3.0, 0.5], [3.0, -0.6]]), 0.1, np.zeros(3))
    assert sorted(m.id for m in members) == [1, 3]


def test_a_neighbour_half_a_metre_away_does_not_replace_a_member_out_of_view():
    # five members stand 0.45-0.5 m apart, inside same_person_m: a member out of view beside a neighbour in view
    # is remembered (it was deleted as the neighbour's duplicate, and its gap merged with the next)
    gt = _tracker()
    near, side = np.array([2.0, 0.4]), np.array([2.0, 0.9])  # 11 deg and 24 deg off the axis: side is out of view
    assert gt.visible(near[None], np.zeros((0, 2)))[0] and not gt.visible(side[None], np.zeros((0, 2)))[0]
    for _ in range(3):
        gt.update(np.array([near, side]), 0.1, np.zeros(3))
    for _ in range(30):  # the side one is no longer detected, longer than the tracker coasts
        members = gt.update(near[None], 0.1, np.zeros(3))
    assert sorted(m.id for m in members) == [1, 2] and gt.tracker.tracks[0].id == 1
    assert next(m for m in members if m.id == 2).pos == pytest.approx(side, abs=0.05)
    # a track born since then, first farther than same_person_m, that comes to stand where the member was is them
    for y in (1.55, 1.55, 1.4, 1.25, 1.1):
        members = gt.update(np.array([near, [2.0, y]]), 0.1, np.zeros(3))
    assert sorted(m.id for m in members) == [1, 3]
    # in the image, hidden 0.5 m behind someone tracked all along, a member no longer detected is a neighbour, kept;
    # one whose place someone tracked all along took over (0.2 m: an id that jumped across) is that someone
    for ahead, kept in ((0.5, [1, 2]), (0.2, [1])):
        gt = _tracker()
        front, behind = np.array([2.0, 0.0]), np.array([2.0 + ahead, 0.0])
        for _ in range(3):
            gt.update(np.array([front, behind]), 0.1, np.zeros(3))
        for _ in range(30):  # longer than the tracker coasts
            members = gt.update(front[None], 0.1, np.zeros(3))
        assert sorted(m.id for m in members) == kept, ahead


def test_someone_hidden_behind_a_remembered_person_is_not_forgotten():
    # a person cut by the image's side is not detected (perceive drops the box) yet hides whoever stands behind
    gt = _tracker()
    at = lambda rng, deg: rng * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])  # noqa: E731
    near, far = at(1.0, 20.0), at(3.5, 18.0)  # the near one's side is out of the image, the far one's is not
    assert not gt.visible(near[None], np.zeros((0, 2)))[0] and gt.visible(far[None], np.zeros((0, 2)))[0]
    for _ in range(3):
        gt.update(np.array([near, far]), 0.1, np.zeros(3))
    for _ in range(30):  # neither is detected: the near one is cut by the side, the far one hidden behind it
        members = gt.update(np.zeros((0, 2)), 0.1, np.zeros(3))
    assert sorted(m.id for m in members) == [1, 2] and not any(m.seen for m in members)


def test_one_box_per_colour_spans_a_torso_split_by_a_nearer_person():
    from ssbl_pb.deploy.perceive import make_detector
    from ssbl_pb.virtual.robot import SimRobot

    robot = SimRobot("default", 11)  # a pair: one 2 m ahead seen side-on, one 3 m ahead facing the camera
    try:
        w = robot.world
        w.base.pose = np.zeros(3)
        w.group.pos[:] = np.array([[2.0, 0.0], [3.0, 0.0]])
        w.group.yaw[:] = np.array([math.pi / 2, math.pi])
        w.invalidate()
        image = robot.render().image
    finally:
        robot.close()
    from ssbl_pb.perception.detection.detectors import ColourDetector
    from ssbl_pb.urdf import HUMAN_COLOURS

    assert len(ColourDetector(HUMAN_COLOURS)(image)) == 3  # the far torso shows on either side of the near one
    detect, torso = make_detector("colour")
    boxes = detect(image)
    assert torso and len(boxes) == 2
    near, far = sorted(boxes, key=lambda b: -b[3])
    assert far[0] + 0.5 * far[2] == pytest.approx(near[0] + 0.5 * near[2], abs=1.5)  # both straight ahead


def test_lockstep_members_keep_one_id_through_leaving_and_reentering_the_view():
    # the real pipeline in lockstep (rendered frames, colour detector, tracker, group memory): the robot faces a
    # pair, turns 100 deg away for 4 s and back; each person is one id throughout
    from ssbl_pb.bench.perception_errors import assign, room_to_odom
    from ssbl_pb.deploy.perceive import Perception
    from ssbl_pb.virtual.robot import SimClock, SimRobot

    robot = SimRobot("default", 11)
    clock = SimClock(robot)
    perception = Perception(robot, clock.now, "colour", RobotParams(), social=SOCIAL, threaded=False)
    ids: dict[int, set[int]] = {}
    away = 0
    try:
        for k in range(120):
            truth = robot.truth()
            pose, centre = np.array(truth["pose"]), np.array(truth["centre"])
            heading = math.remainder(math.atan2(*(centre - pose[:2])[::-1]) - pose[2], 2 * math.pi)
            turn = heading + (math.radians(100) if 40 <= k < 80 else 0.0)
            robot.send(np.array([0.0, 0.0, float(np.clip(2.0 * turn, -1.0, 1.0))]))
            odo = robot.odometry()
            perception.odometry.append((odo.stamp, odo.pose))
            perception.step()
            est, _ = perception.snapshot()
            members = est.members if est is not None else []
            away += 60 <= k < 80 and not any(m.seen for m in members)
            _, owner = assign(np.array([m.pos for m in members]), room_to_odom(robot.start_pose,
                                                                               np.array(truth["members"])), 0.75)
            for m, j in zip(members, owner, strict=True):
                if j >= 0:
                    ids.setdefault(int(j), set()).add(m.id)
            clock.sleep(0.1)
    finally:
        robot.close()
    assert away >= 15  # nobody in view for 1.5 s and more (the tracker drops a track after 10 frames, 0.67 s)
    assert sorted(ids) == [0, 1] and all(len(v) == 1 for v in ids.values()), ids


def test_lockstep_members_carry_the_facing_the_colour_detector_reads():
    # deploy's pipeline on rendered frames: the tracked members' facing (odometry frame) is the virtual Pepper's
    # people's, within the spread the filter reports (here the farther person is half hidden behind the nearer
    # one, and their facing stays unknown)
    from ssbl_pb.bench.perception_errors import assign, room_to_odom
    from ssbl_pb.deploy.perceive import Perception
    from ssbl_pb.virtual.robot import SimClock, SimRobot

    robot = SimRobot("default", 11)
    clock = SimClock(robot)
    perception = Perception(robot, clock.now, "colour", RobotParams(), social=SOCIAL, threaded=False)
    try:
        for _ in range(30):  # turn to face the pair and watch it
            truth = robot.truth()
            pose, centre = np.array(truth["pose"]), np.array(truth["centre"])
            heading = math.remainder(math.atan2(*(centre - pose[:2])[::-1]) - pose[2], 2 * math.pi)
            robot.send(np.array([0.0, 0.0, float(np.clip(2.0 * heading, -1.0, 1.0))]))
            odo = robot.odometry()
            perception.odometry.append((odo.stamp, odo.pose))
            perception.step()
            clock.sleep(0.1)
        est, _ = perception.snapshot()
        members = [m for m in est.members if m.facing is not None]
        true_yaw = robot.world.group.yaw[:2] - robot.start_pose[2]  # the odometry frame turns by the start yaw
        _, owner = assign(np.array([m.pos for m in members]), room_to_odom(robot.start_pose,
                                                                           np.array(robot.truth()["members"])), 0.75)
    finally:
        robot.close()
    assert len(members) >= 1 and (owner >= 0).all()
    errors = [abs(math.remainder(m.facing - true_yaw[j], 2 * math.pi)) for m, j in zip(members, owner, strict=True)]
    assert all(e <= max(math.radians(5), 2.5 * m.facing_std) for e, m in zip(errors, members, strict=True)), errors
    assert min(m.facing_std for m in members) < math.radians(5)  # one of them shows its front: read finely


def test_movenets_facing_filter_leaves_out_a_facing_turned_back_unless_it_comes_again_and_again():
    cam = sim_camera(RobotParams(), 320, 240)
    gt = GroupTracker(cam, TrackerParams(dt=0.1, birth_hits=2, meas_std=0.05), KEYPOINT_GROUP, social=SOCIAL)
    person = np.array([[2.0, 0.0]])  # straight ahead, looking at the robot: facing pi in the odometry frame
    std = np.array([math.radians(10)])

    def frame(phi: float) -> float:
        members = gt.update(person, 0.1, np.zeros(3), np.array([phi]), std)
        return members[0].facing if members and members[0].facing is not None else math.nan

    for _ in range(5):
        frame(0.0)
    assert abs(math.remainder(frame(math.pi) - math.pi, 2 * math.pi)) < 1e-6  # one flip: left out
    assert abs(math.remainder(frame(0.0) - math.pi, 2 * math.pi)) < 1e-6
    facings = [frame(math.pi) for _ in range(GroupParams().facing_switch)]
    assert abs(math.remainder(facings[-2] - math.pi, 2 * math.pi)) < 1e-6  # two in a row: still left out
    assert abs(math.remainder(facings[-1], 2 * math.pi)) < 1e-6  # three: the person turned (or was flipped)
    gt = _tracker()  # the colour chain's filter takes every facing in
    for _ in range(5):
        frame(0.0)
    assert abs(math.remainder(frame(math.pi) - math.pi, 2 * math.pi)) > math.radians(20)


def test_group_params_name_the_bad_field():
    from ssbl_pb.params import ConfigError
    from ssbl_pb.perception.groups.estimate import GroupParams

    for field, value, expected in [("forget_frames", 0, "an integer >= 1"), ("facing_switch", True, "an integer >= 1"),
                                   ("same_person_m", -0.1, "metres > 0"),
                                   ("edge_margin_m", float("nan"), "a number >= 0"),
                                   ("facing_gate_deg", 0.0, r"degrees in \(0, 180\]")]:
        with pytest.raises(ConfigError, match=f"group.{field} = .*expected {expected}"):
            GroupParams(**{field: value})
