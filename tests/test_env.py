"""The Gymnasium env: registration, check_env for the three modes, seeding, the success rule, scenarios."""

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ssbl_pb  # noqa: F401  (registers the env)
from ssbl_pb.core.observation import OBS_SIZE, decode_members
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.env.rooms.scenarios import ScenarioMix


@pytest.mark.parametrize("mode", ["vector", "camera", "camera_speed"])
def test_check_env(mode):
    env = gym.make("ssbl_pb/ApproachGroup-v0", obs_mode=mode)
    check_env(env.unwrapped if mode == "vector" else env.env.env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.close()


def rollout(env, seed, steps=40):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [obs]
    for _ in range(steps):
        obs, r, te, tr, _ = env.step(env.action_space.sample())
        out.append(np.append(obs, r))
        if te or tr:
            break
    return out


def test_seeded_reset_is_reproducible():
    env = gym.make("ssbl_pb/ApproachGroup-v0", scenario="mixed")
    a = rollout(env, 5)
    rollout(env, 6)
    b = rollout(env, 5)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    c = rollout(env, 7)
    assert not np.array_equal(a[0], c[0])


def place_at_slot(env: ApproachGroupEnv, offset=(0.0, 0.0), yaw_error=0.0, speed=0.0):
    env.reset(seed=3)
    w = env.world
    # a robot standing in the o-space gap makes the group re-form around it: let it settle first
    for _ in range(60):
        slot = w.group.free_slot(w.robot_pose[:2])
        to_c = w.group.centre - slot
        w.base.reset(np.array([*slot, math.atan2(to_c[1], to_c[0])]))
        w.group.step(w.robot_pose[:2], w.params.dt)
    slot = w.group.free_slot(w.robot_pose[:2])
    to_c = w.group.centre - slot
    yaw = math.atan2(to_c[1], to_c[0]) + yaw_error
    w.base.reset(np.array([slot[0] + offset[0], slot[1] + offset[1], yaw]))
    w.base.vel = np.array([speed * math.cos(yaw), speed * math.sin(yaw), 0.0])
    env.refresh()  # the slot, and clearances the placed robot has not closed (proximity cost)
    keep = speed / env.robot_params.max_speed
    return env.step(np.array([keep, 0.0], dtype=np.float32))


def test_success_at_the_slot_stopped_and_facing():
    env = ApproachGroupEnv()
    _, r, terminated, _, info = place_at_slot(env)
    assert info["success"] and terminated and r > 1.0


@pytest.mark.parametrize("kwargs", [{"offset": (0.45, 0.0)}, {"yaw_error": math.radians(40)}, {"speed": 0.3}])
def test_no_success_off_slot_turned_away_or_moving(kwargs):
    env = ApproachGroupEnv()
    _, _, terminated, _, info = place_at_slot(env, **kwargs)
    assert not info["success"] and not terminated


def test_near_the_centre_is_not_success():
    env = ApproachGroupEnv()
    env.reset(seed=1)
    w = env.world
    c = w.group.centre0
    member = w.group.pos[0]
    # half-way between the centre and a member: within 1.3 m of the centre but not at the slot
    p = c + 0.3 * (member - c) / np.linalg.norm(member - c)
    w.base.reset(np.array([*p, 0.0]))
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert not info["success"]


def test_intimate_zone_intrusion_ends_episode_as_failure():
    env = ApproachGroupEnv()
    env.reset(seed=2)
    w = env.world
    m = w.group.pos[0]
    w.base.reset(np.array([m[0] - 0.9, m[1], 0.0]))  # footprint edge 0.66 m from the centre: clearance 0.38
    _, r, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["violation"] and terminated and not info["success"]
    assert info["episode_terms"]["violation"] == -1.0


def test_proximity_cost_charges_driving_at_a_member_not_standing_beside_it():
    env = ApproachGroupEnv(groups="paper")  # the distances below are the paper circle's (2 m between the pair)
    env.reset(seed=2)
    w, g = env.world, env.world.group
    m = g.pos[0]
    u = (m - g.centre) / np.linalg.norm(m - g.centre)
    # outside member 0 on the ray from the centre, 1.3 m from it (clearance 0.78 m, outside the 0.3 m band):
    # driving toward the centre (action (1, 0) in the approach frame) drives at the member
    start = m + 1.3 * u
    w.base.reset(np.array([*start, math.atan2(-u[1], -u[0])]))
    env.refresh()
    cost, clearances = 0.0, []
    for _ in range(20):
        _, _, term, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        cost += info["terms"]["proximity"]
        clearances.append(w.human_clearance()[0])
        if term:
            break
    assert info["violation"] and min(clearances) < 0.45
    # it crossed the whole band (0.75 -> 0.45 m): the cost is about the band's mean depth times its width
    assert -0.3 < cost < -0.1
    # beside the member, in the band (clearance 0.73 m) but outside its personal zone and the joining range, so
    # nobody else moves: standing still costs nothing, moving at it does
    per_step = {}
    for action in (0.0, 1.0):
        env.reset(seed=2)
        w.base.reset(np.array([*(g.centre0 + (np.linalg.norm(m - g.centre0) + 1.25) * u), math.atan2(-u[1], -u[0])]))
        env.refresh()
        assert 0.45 < w.human_clearance()[0] < 0.75
        per_step[action] = env.step(np.array([action, 0.0], dtype=np.float32))[4]["terms"]["proximity"]
    assert per_step[0.0] == 0.0 and per_step[1.0] < 0.0


def test_route_keeps_the_footprint_corners_out_of_the_intimate_zone():
    env = ApproachGroupEnv(task={"route_margin": 0.0})
    env.reset(seed=0)
    g = env.world.group
    # a point on the far side of the group from the slot: its way goes around at the keep-out radius
    far = g.centre + 4.0 * (g.centre - env.slot()) / np.linalg.norm(g.centre - env.slot())
    keep_out = g.radius + env.social.human_radius + env.robot_params.reach + env.task.intimate_zone
    from ssbl_pb.core.reward import route_distance

    assert env.keep_out() == pytest.approx(keep_out + env.task.route_margin)
    pose = np.array([*far, 0.0])
    env.world.base.pose = pose
    env.refresh()  # the shaping potential is minus the way around the group (standing still)
    assert env.sim.potential[0] == pytest.approx(-route_distance(far, env.slot(), g.centre, keep_out))
    assert env.robot_params.reach == pytest.approx(0.5 * math.hypot(0.48, 0.43))


def test_truncation_at_max_steps():
    env = ApproachGroupEnv(task={"max_steps": 5})
    env.reset(seed=0)
    flags = [env.step(np.zeros(2, dtype=np.float32))[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]


def test_vector_observation_layout():
    env = ApproachGroupEnv(scenario="circular-4")
    obs, info = env.reset(seed=4)
    assert obs.shape == (OBS_SIZE,) and info["n_humans"] == 4
    members, _ = decode_members(obs)
    assert len(members) == 4
    # nearest first, in the body frame
    d = np.hypot(*members.T)
    assert np.all(np.diff(d) >= 0)
    w = env.world
    true = np.sort(np.hypot(*(w.group.pos - w.robot_pose[:2]).T))
    assert d == pytest.approx(true, abs=1e-5)


def test_scenarios_parse_and_sample():
    rng = np.random.default_rng(0)
    sizes = {ScenarioMix("mixed").sample(rng)[0] for _ in range(200)}
    assert sizes == {2, 3, 4, 5}
    assert ScenarioMix("circular-4").sample(rng) == (4, "circular", "any")
    assert ScenarioMix("behind").sample(rng)[2] == "behind"
    with pytest.raises(ValueError, match="scenario 'blob'"):
        ScenarioMix("blob")


def test_turn_option_adds_an_action():
    env = gym.make("ssbl_pb/ApproachGroup-v0", task={"turn": True})
    assert env.action_space.shape == (3,)


def test_unknown_env_option_rejected():
    with pytest.raises(ValueError, match="unknown key"):
        ApproachGroupEnv(task={"max_step": 5})


def test_camera_yaml_sets_projection_and_pose(tmp_path):
    yaml_text = """image_width: 640
image_height: 480
camera_name: test
camera_matrix: {rows: 3, cols: 3, data: [500.0, 0.0, 319.5, 0.0, 500.0, 239.5, 0.0, 0.0, 1.0]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [0.0, 0.0, 0.0, 0.0, 0.0]}
rectification_matrix: {rows: 3, cols: 3, data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]}
projection_matrix: {rows: 3, cols: 4, data: [500.0, 0.0, 319.5, 0.0, 0.0, 500.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0]}
"""
    path = tmp_path / "cam.yaml"
    path.write_text(yaml_text)
    env = gym.make("ssbl_pb/ApproachGroup-v0", obs_mode="camera", camera_yaml=str(path), camera_width=64,
                   camera_height=48)
    core = env.unwrapped
    assert core.robot_params.camera_hfov_deg == pytest.approx(2 * math.degrees(math.atan(320 / 500)), abs=0.2)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (48, 64, 3)


def test_calibration_yamls_overlay_the_defaults(tmp_path):
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.params import ConfigError

    (tmp_path / "dyn.yaml").write_text("latency_s: 0.2\nmax_accel: 0.4\n")
    (tmp_path / "humans.yaml").write_text("personal_radius: 1.1\nmax_speed: 1.2\n")
    (tmp_path / "room.yaml").write_text("world:\n  room_size: [8.0, 7.0]\nmap_to_room: {}\n")
    env = make_env(robot_yaml=str(tmp_path / "dyn.yaml"), social_yaml=str(tmp_path / "humans.yaml"),
                   room_yaml=str(tmp_path / "room.yaml"), robot={"max_speed": 0.3})
    core = env.unwrapped
    assert core.robot_params.latency_s == 0.2 and core.robot_params.max_accel == 0.4
    assert core.robot_params.max_speed == 0.3  # explicit values win
    assert core.social.personal_radius == 1.1 and core.world_params.room_size == (8.0, 7.0)
    (tmp_path / "bad.yaml").write_text("latency: 0.2\n")
    with pytest.raises(ConfigError, match="latency"):
        make_env(robot_yaml=str(tmp_path / "bad.yaml"))
    with pytest.raises(ConfigError, match="world"):
        make_env(room_yaml=str(tmp_path / "dyn.yaml"))


def test_recorded_states_are_copies_of_the_state():
    env = ApproachGroupEnv(scenario="mixed", record=True)
    env.reset(seed=4)
    for _ in range(30):
        env.step(np.array([1.0, 0.5], dtype=np.float32))
    first = env.trajectory[0]
    assert not np.array_equal(first["robot"], env.world.robot_pose)  # it moved, the record did not
    assert not np.array_equal(first["members"], env.world.group.pos) or env.world.group.n == 0
