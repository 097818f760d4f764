"""The safety shield: footprint geometry, the closing-speed limit, and the closed loop never entering a zone."""

import dataclasses
import math

import numpy as np
import pytest

from ssbl_pb.core.observation import MEMBER_X, MEMBER_Y, MEMBERS, OBS_SIZE, POS_SCALE
from ssbl_pb.core.shield import (
    RULES,
    SafetyShield,
    ShieldParams,
    brake_closing,
    footprint_clearance,
    shield_action,
    shield_actions,
)
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.env.view.world import box_circle_distance
from ssbl_pb.errors import UserError
from ssbl_pb.params import ConfigError

P = ShieldParams()


def obs_with(members, members_vel=None, heading=0.0):
    """A Vector observation holding only what the shield reads: members (approach frame, m) and heading."""
    obs = np.zeros(OBS_SIZE, dtype=np.float32)
    members_vel = np.zeros((len(members), 2)) if members_vel is None else members_vel
    for i, (p, v) in enumerate(zip(members, members_vel, strict=True)):
        obs[14 + 5 * i: 19 + 5 * i] = (p[0] / POS_SCALE, p[1] / POS_SCALE, v[0], v[1], 1.0)
    obs[39] = heading / math.pi
    return obs


REACH = math.hypot(0.24, 0.215)  # the footprint's circumscribed radius


def test_footprint_clearance_is_the_circumscribed_circles_a_lower_bound_at_any_heading():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2, 2, (50, 2))
    ours, toward = footprint_clearance(pts, 0.0, P)
    assert np.allclose(ours, np.hypot(pts[:, 0], pts[:, 1]) - REACH - 0.28)
    assert np.allclose(np.hypot(toward[:, 0], toward[:, 1]), 1.0)
    for heading in np.linspace(-math.pi, math.pi, 13):  # turning never brings the box closer than that
        box = box_circle_distance(np.array([0.0, 0.0, heading]), (0.24, 0.215), pts) - 0.28
        assert np.all(ours <= box + 1e-12)
        assert np.allclose(footprint_clearance(pts, heading, P)[0], ours)
    # a member straight ahead: direction +x, the gap from a corner's circle
    c, u = footprint_clearance(np.array([[1.0, 0.0]]), 0.0, P)
    assert c[0] == pytest.approx(1.0 - REACH - 0.28) and np.allclose(u[0], [1.0, 0.0])


def test_closing_speed_is_limited_to_what_the_base_can_still_brake():
    # a member straight ahead with 0.6 m between the footprint's circle and its body
    member = np.array([[REACH + 0.28 + 0.6, 0.0]])
    out = shield_action(obs_with(member), np.array([1.0, 0.0]), P)
    allow = math.sqrt(2 * 0.2 * (0.6 - 0.5))  # 0.2 m/s
    assert out[0] * 0.35 == pytest.approx(allow) and out[1] == 0.0
    # sideways motion past the member is untouched; moving away is untouched
    assert np.allclose(shield_action(obs_with(member), np.array([0.0, 1.0]), P), [0.0, 1.0])
    assert np.allclose(shield_action(obs_with(member), np.array([-0.9, 0.3]), P), [-0.9, 0.3])
    # at the limit: no closing at all, and a diagonal command keeps only its sideways part
    at_limit = np.array([[REACH + 0.28 + 0.5, 0.0]])
    assert np.allclose(shield_action(obs_with(at_limit), np.array([0.7, 0.7]), P), [0.0, 0.7], atol=1e-6)
    # a member walking toward the robot: the robot must back off
    out = shield_action(obs_with(at_limit, np.array([[-0.1, 0.0]])), np.zeros(2), P)
    assert out[0] == pytest.approx(-0.1 / 0.35)


def test_brake_closing_gives_each_point_its_own_clearance():
    ahead, left = [REACH + 0.28 + 0.8, 0.0], [0.0, REACH + 0.28 + 0.7]
    v = brake_closing(np.array([0.3, 0.3]), np.array([ahead, left]), np.array([0.6, 0.5]), P)
    # ahead: 0.8 m of gap, braked for 0.6 -> sqrt(2 * 0.2 * 0.2) = 0.283 m/s; left: 0.7 for 0.5 -> the same
    assert v == pytest.approx([math.sqrt(0.08), math.sqrt(0.08)])
    v = brake_closing(np.array([0.3, 0.3]), np.array([ahead, left]), np.array([0.75, 0.5]), P)
    assert v == pytest.approx([math.sqrt(0.02), math.sqrt(0.08)])  # 0.05 m to go ahead: 0.141 m/s
    assert brake_closing(np.array([-0.3, 0.1]), np.array([ahead]), np.array([2.0]), P) == pytest.approx([-0.3, 0.1])
    assert brake_closing(np.array([0.3, 0.1]), np.zeros((0, 2)), np.zeros(0), P) == pytest.approx([0.3, 0.1])


def test_every_sector_keeps_its_limit_between_obstacles_on_two_sides():
    # the scan (m) of a robot that drove into a desk in the meeting room: obstacles ahead-left (sectors 0-4) and
    # behind-right (15-17). Braking for each sector in turn gave back speed toward the earlier ones (0.14 m/s
    # toward sector 0 when driving at 270 deg); the shielded command closes on none faster than it can brake.
    from ssbl_pb.core.observation import BASE_SIZE, SCAN_RANGE, SCAN_RAYS

    scan = np.array([0.39, 0.4, 0.33, 0.34, 0.37, 0.5, 1.37, 3, 3, 2.3, 3, 3, 3, 3, 3, 0.49, 0.44, 0.44, 0.83, 1.16,
                     1.57, 3, 3, 3])
    obs = obs_with(np.zeros((0, 2)))
    obs[BASE_SIZE:] = scan / SCAN_RANGE
    for angle in np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False):
        v = shield_action(obs, np.array([math.cos(angle), math.sin(angle)]), P) * P.max_speed
        for k, r in enumerate(scan):
            a = 2.0 * math.pi * k / SCAN_RAYS
            allow = math.sqrt(2.0 * P.brake_accel * max(r - REACH - P.obstacle_clearance_min, 0.0))
            assert v[0] * math.cos(a) + v[1] * math.sin(a) <= allow + 1e-6, (math.degrees(angle), k)
    # backing away from both (toward the open sectors 7-14) passes untouched
    away = np.array([math.cos(math.radians(150)), math.sin(math.radians(150))]) * 0.8
    assert np.allclose(shield_action(obs, away, P), away, atol=1e-6)


def test_a_command_stopped_by_an_obstacle_slides_along_it_and_one_stopped_by_a_member_does_not():
    from ssbl_pb.core.observation import BASE_SIZE, SCAN_RANGE

    obs = obs_with(np.zeros((0, 2)))
    obs[BASE_SIZE:] = 1.0
    obs[BASE_SIZE + 0] = (REACH + P.obstacle_clearance_min) / SCAN_RANGE  # a speck dead ahead, at the margin
    out = shield_action(obs, np.array([1.0, 0.0]), P)
    assert abs(out[1]) >= 0.25 and abs(out[0]) < 1e-6  # it slides sideways, neither toward the speck nor back
    assert shield_action(obs, np.array([0.2, 0.0]), P) == pytest.approx([0.0, 0.0], abs=1e-6)  # slow: it stops
    # a member dead ahead at the intimate zone's edge: no sliding round a person
    member = obs_with(np.array([[REACH + 0.28 + P.clearance_min, 0.0]]))
    assert shield_action(member, np.array([1.0, 0.0]), P) == pytest.approx([0.0, 0.0], abs=1e-6)


def test_safety_shield_shields_every_row_of_a_batch():
    near = obs_with(np.array([[0.24 + 0.28 + 0.6, 0.0]]))
    far = obs_with(np.array([[3.0, 1.0]]))
    obs = np.stack([far, near, near])
    act = np.array([[1.0, 0.0], [1.0, 0.0], [0.7, 0.7]], dtype=np.float32)
    out = SafetyShield(P)(obs, act)
    assert out.shape == act.shape
    for o, a, got in zip(obs, act, out, strict=True):  # each row as if shielded alone
        assert np.allclose(got, shield_action(o, a, P), atol=1e-6)
    assert out[1, 0] < 0.99 and out[2, 0] < 0.69  # the rows after the first were braked too


def test_far_members_and_no_members_leave_the_action_alone():
    a = np.array([0.9, -0.4], dtype=np.float32)
    assert np.allclose(shield_action(obs_with(np.array([[3.0, 1.0]])), a, P), a)
    assert np.allclose(shield_action(obs_with(np.zeros((0, 2))), a, P), a)


def test_shielded_robot_driving_at_a_member_stops_outside_the_intimate_zone():
    from ssbl_pb.env.gymenv.wrappers import ShieldWrapper

    for shielded in (False, True):
        core = ApproachGroupEnv()
        env = ShieldWrapper(core) if shielded else core
        env.reset(seed=2)
        w, g = core.world, core.world.group
        u = (g.pos[0] - g.centre) / np.linalg.norm(g.pos[0] - g.centre)
        w.base.reset(np.array([*(g.pos[0] + 1.5 * u), math.atan2(-u[1], -u[0])]))
        if shielded:
            core.refresh()
            env._obs = core.observe()
        info = {}
        for _ in range(60):  # full speed toward the centre, through member 0
            _, _, term, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
            if term:
                break
        assert info["violation"] is (not shielded)
        if shielded:
            assert w.human_clearance().min() >= 0.45


def test_safety_shield_config_and_loading(tmp_path):
    from ssbl_pb.training.config import load_config

    with pytest.raises(ConfigError, match="safety_shield"):
        load_config(None, {"safety_shield": "on"})
    # on by default for the Vector mode; camera modes cannot feed it and train without it
    assert load_config(None).shield_active
    assert not load_config(None, {"obs_mode": "camera", "encoder": "cnn"}).shield_active
    with pytest.raises(ConfigError, match="brake_accel"):
        ShieldParams(brake_accel=1.0)
    # a run whose config has the shield on loads with it (and acts through it), one without loads without
    import yaml
    from stable_baselines3 import PPO

    from ssbl_pb.agents.trained import load_trained

    env = ApproachGroupEnv()
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=0, device="cpu").save(tmp_path / "model.zip")
    for on in (True, False):
        (tmp_path / "config.yaml").write_text(yaml.safe_dump({"obs_mode": "vector", "safety_shield": on}))
        policy = load_trained(str(tmp_path), env.observation_space)
        assert (policy.shield is not None) is on
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert action.shape == (2,)


def test_shipped_policy_uses_the_shield_unless_told_not_to():
    from ssbl_pb.agents.trained import load_trained

    space = ApproachGroupEnv().observation_space
    assert load_trained("vector", space).shield is not None
    assert load_trained("vector", space, shield=False).shield is None


def test_evaluate_shield_flag_is_checked():
    import subprocess
    import sys
    from pathlib import Path

    tool = Path(__file__).resolve().parents[1] / "tools" / "evaluate.py"
    res = subprocess.run([sys.executable, str(tool), "--policy", "vector", "--shield", "maybe", "--out", "x"],
                         capture_output=True, text=True)
    assert res.returncode == 2 and "--shield" in res.stderr


def test_evaluation_shield_follows_a_calibrated_robot(tmp_path):
    from ssbl_pb.analysis.evaluation import Setup

    robot = tmp_path / "robot.yaml"
    robot.write_text("max_accel: 0.15\n")
    _, policy = Setup("vector", env_kwargs=(("robot_yaml", str(robot)),))()
    assert policy.shield.params.brake_accel == pytest.approx(0.1)  # 2/3 of the calibrated limit
    _, policy = Setup("vector")()
    assert policy.shield.params.brake_accel == pytest.approx(0.2)


def test_braking_for_an_obstacle_never_gives_back_speed_toward_a_member():
    # a narrow way: a member ahead-left, a desk ahead-right (sectors 21-23 at 0.45 m). Braking for the desk after
    # the member removed speed toward the desk and with it gave speed back toward the member; every command now
    # closes on each of them no faster than the base can brake.
    from ssbl_pb.core.observation import BASE_SIZE, SCAN_RANGE, SCAN_RAYS

    member = np.array([[0.6, 0.75]])
    obs = obs_with(member)
    scan = np.full(SCAN_RAYS, SCAN_RANGE)
    scan[[21, 22, 23]] = 0.45
    obs[BASE_SIZE:] = scan / SCAN_RANGE
    d = math.hypot(*member[0])
    ux, uy = member[0] / d
    allow_member = math.sqrt(2.0 * P.brake_accel * max(d - REACH - 0.28 - P.clearance_min, 0.0))
    worst = 0.0
    for angle in np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False):
        v = shield_action(obs, np.array([math.cos(angle), math.sin(angle)]), P) * P.max_speed
        worst = max(worst, v[0] * ux + v[1] * uy - allow_member)
        for k, r in enumerate(scan):
            a = 2.0 * math.pi * k / SCAN_RAYS
            allow = math.sqrt(2.0 * P.brake_accel * max(r - REACH - P.obstacle_clearance_min, 0.0))
            assert v[0] * math.cos(a) + v[1] * math.sin(a) <= allow + 1e-6, (math.degrees(angle), k)
    assert worst <= 1e-6


def _wall_scan(obs: np.ndarray, gap: float) -> None:
    """Range-scan entries of a straight wall ``gap`` m ahead (x = gap in the approach frame, endless in y): each
    15 deg sector's nearest point of it, or nothing within 3 m."""
    for k in range(24):
        a = math.radians(15.0 * k if k <= 12 else 15.0 * k - 360.0)
        nearest = 0.0 if abs(a) <= math.radians(7.5) else abs(a) - math.radians(7.5)
        r = gap / math.cos(nearest) if nearest < math.pi / 2 else math.inf
        obs[40 + k] = min(r / 3.0, 1.0)


def test_a_robot_already_closing_too_fast_brakes_before_it_turns():
    """The base reaches a command at 0.3 m/s^2: a robot driving at a wall at full speed and asked to turn 60 deg
    spent that on the turn and ran on into the wall (a desk's corner in the lab room). The shield now brakes the
    base's own velocity first when a period toward the command would leave it too fast, and the footprint's
    circle keeps clear of the wall."""
    from ssbl_pb.core.base import base_step

    pose, vel, queue = np.array([0.0, 0.0, 0.0]), np.array([0.35, 0.0, 0.0]), np.zeros((1, 3))
    wall_x = REACH + 0.38  # 0.38 m between the footprint's circle and the wall: 0.335 m/s to brake for at 0.2 m/s^2
    wish = np.array([math.cos(math.radians(60)), math.sin(math.radians(60))])
    closest = math.inf
    for _ in range(60):
        obs = np.zeros(OBS_SIZE, dtype=np.float32)
        obs[5:7] = vel[:2] / 0.35
        _wall_scan(obs, wall_x - pose[0])
        cmd = shield_action(obs, wish, P)
        base_step(0.35, 1.0, 0.3, 0.75, 0.0, 0, 0.0, 0.1, pose, vel, queue, cmd[0] * 0.35, cmd[1] * 0.35, 0.0)
        closest = min(closest, wall_x - pose[0] - REACH)
    # the circle (hence every corner at any heading) keeps about the shield's 0.1 m; turning first came to 0.074
    assert closest > 0.09
    assert pose[1] > 1.0  # and the robot does go its way along it


def test_braking_first_only_when_a_period_toward_the_command_is_not_enough():
    """A velocity a little over its limit keeps the policy's turn when one period toward it brakes enough, and is
    braked straight when it does not."""
    obs = np.zeros(OBS_SIZE, dtype=np.float32)
    _wall_scan(obs, REACH + 0.38)  # allow 0.335 m/s toward the wall
    turn = np.array([0.0, 1.0])  # straight along the wall: one period takes 0.03 m/s off the closing
    obs[5:7] = (0.35 / 0.35, 0.0)  # 0.015 over: the turn brakes enough
    assert np.allclose(shield_action(obs, turn, P), turn, atol=1e-6)
    obs[5:7] = (0.35 / 0.35, 0.0)
    _wall_scan(obs, REACH + 0.3)  # allow 0.28 m/s: 0.07 over, more than a period's 0.03
    out = shield_action(obs, turn, P)
    assert out[1] == pytest.approx(0.0, abs=1e-6) and out[0] * 0.35 == pytest.approx(math.sqrt(0.4 * 0.2), abs=1e-3)


def test_a_policys_shield_at_place_travels_to_evaluation_and_deploy(tmp_path):
    """Config ``shield_at_place``: refused when not a bool, by name; a run with it loads with a shield keeping the
    place's 0.6 m near the place, evaluates with it on a calibrated robot too, and deploys with it; a run without
    it keeps none."""
    import yaml
    from stable_baselines3 import PPO

    from ssbl_pb.agents.trained import load_trained, shield_at_place
    from ssbl_pb.analysis.evaluation import Setup
    from ssbl_pb.core.task import TaskParams
    from ssbl_pb.deploy.loop import deploy_shield
    from ssbl_pb.params import RobotParams, SocialParams
    from ssbl_pb.training.config import load_config

    with pytest.raises(ConfigError, match="shield_at_place"):
        load_config(None, {"shield_at_place": "yes"})
    env = ApproachGroupEnv()
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=0, device="cpu").save(tmp_path / "model.zip")
    cfg = {"obs_mode": "vector", "safety_shield": True}
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(cfg))
    assert not shield_at_place(str(tmp_path)) and not shield_at_place("sffm")
    assert load_trained(str(tmp_path)).shield.params.place_clearance == 0.0
    (tmp_path / "config.yaml").write_text(yaml.safe_dump({**cfg, "shield_at_place": True}))
    params = load_trained(str(tmp_path)).shield.params
    assert (params.clearance_min, params.place_clearance, params.place_arrival_speed) == pytest.approx(
        (0.50, 0.60, 0.05))
    assert params.ospace_keep_out
    robot = tmp_path / "robot.yaml"
    robot.write_text("max_accel: 0.15\n")
    _, policy = Setup(str(tmp_path), env_kwargs=(("robot_yaml", str(robot)),))()
    assert policy.shield.params.place_clearance == pytest.approx(0.60)
    assert policy.shield.params.brake_accel == pytest.approx(0.1)
    on_robot = deploy_shield(RobotParams(), SocialParams(), TaskParams(), 0.45, shield_at_place(str(tmp_path)))
    assert (on_robot.clearance_min, on_robot.place_clearance, on_robot.place_arrival_speed) == pytest.approx(
        (0.55, 0.60, 0.05))
    assert on_robot.ospace_keep_out and not ShieldParams.from_env(RobotParams(), SocialParams(), TaskParams()
                                                                  ).ospace_keep_out


def test_near_its_place_the_shield_keeps_the_places_clearance():
    """A member 0.75 m ahead (body to footprint circle), the robot commanded at it at full speed, the range scan
    seeing nothing: with the place 2 m away the shield allows sqrt(2 a (0.75 - 0.5)); with the place at the robot
    or 1.2 m away (the passing ramp's start), sqrt(2 a (0.75 - 0.6)); half way through that ramp (1.4 m), the
    clearance kept is 0.55 m. With a desk 1.25 m behind (half way through the scan's gate) it is 0.55 m at 1.2 m;
    with one 0.9 m behind, only the place's own ramp holds (0.5 m at 1.2 m; 0.55 m at 0.45 m). Without
    ``place_clearance`` nothing changes."""
    from ssbl_pb.core.observation import BASE_SIZE, SCAN_RANGE
    from ssbl_pb.core.shield import CLEARANCE_FAR, CLEARANCE_NEAR, ROOM_FAR, ROOM_NEAR

    assert (CLEARANCE_NEAR, CLEARANCE_FAR, ROOM_NEAR, ROOM_FAR) == (1.2, 1.6, 1.0, 1.5)
    a = P.brake_accel
    at_place = ShieldParams(place_clearance=0.6)
    member_x = 0.75 + REACH + P.human_radius
    back = BASE_SIZE + 12  # the ray straight behind (ray k points at 2 pi k / 24)
    for place, desk, kept in ((2.0, None, 0.5), (0.0, None, 0.6), (1.2, None, 0.6), (1.4, None, 0.55),
                              (1.2, 1.25, 0.55), (1.2, 0.9, 0.5), (0.45, 0.9, 0.55)):
        obs = obs_with([(member_x, 0.0)])
        obs[BASE_SIZE:] = 1.0
        if desk is not None:
            obs[back] = desk / SCAN_RANGE
        obs[0] = place / POS_SCALE
        for params, c_min in ((at_place, kept), (P, 0.5)):
            v = shield_action(obs, np.array([1.0, 0.0], dtype=np.float32), params)[0] * P.max_speed
            assert v == pytest.approx(math.sqrt(2 * a * (0.75 - c_min)), abs=1e-3), (place, desk, params)


def test_near_its_place_the_shield_caps_the_speed_to_arrive_slowly():
    """No member in view, full speed asked straight ahead: with ``place_arrival_speed`` 0.05 the speed allowed is
    sqrt(0.05^2 + 2 a (d - 0.3)) at d m from the place (a = 0.2: 0.206 m/s at 0.4 m, 0.05 within 0.3 m, the full
    0.35 beyond 0.6 m), in the direction asked; without it, nothing changes; a bad value is refused by name; and
    it holds only where the robot keeps the clearance asked of it from every member."""
    from ssbl_pb.core.shield import place_speed_cap

    slow = ShieldParams(place_arrival_speed=0.05)
    assert place_speed_cap(0.4, 0.05, 0.2) == pytest.approx(math.sqrt(0.05 ** 2 + 2 * 0.2 * 0.1))
    for place, speed in ((1.0, P.max_speed), (0.4, 0.2062), (0.2, 0.05), (0.0, 0.05)):
        obs = obs_with(np.zeros((0, 2)))
        obs[0] = place / POS_SCALE
        cmd = np.array([0.6, 0.8], dtype=np.float32)
        out = shield_action(obs, cmd, slow) * P.max_speed
        assert np.hypot(*out) == pytest.approx(speed, abs=1e-3), place
        assert out[1] / out[0] == pytest.approx(0.8 / 0.6, rel=1e-5)
        assert shield_action(obs, cmd, P) == pytest.approx(cmd, abs=1e-6)
    with pytest.raises(ConfigError, match="place_arrival_speed"):
        ShieldParams(place_arrival_speed=-0.1)
    # a member beside it, 0.2 m from the place, driving straight on (not closing on the member): capped where it
    # keeps the place's 0.6 m from the member, not where it is closer (stopping would leave it there)
    both = ShieldParams(place_clearance=0.6, place_arrival_speed=0.05)
    for beside, speed in ((0.65, 0.05), (0.55, P.max_speed)):
        obs = obs_with([(0.0, -(REACH + P.human_radius + beside))])
        obs[0] = 0.2 / POS_SCALE
        out = shield_action(obs, np.array([1.0, 0.0], dtype=np.float32), both) * P.max_speed
        assert np.hypot(*out) == pytest.approx(speed, abs=1e-3), beside


def test_at_place_the_approach_ends_outside_the_members_repulsion_zone():
    """Closed loop, the shipped policy on 10 default episodes: with the place's clearance kept near the place,
    every episode still succeeds and ends with the robot's centre at least 1.18 m from every member (their
    repulsion zone is 1.2 m; without it the policy ends 5-10 cm inside)."""
    from ssbl_pb.agents.rollout import run_episode
    from ssbl_pb.agents.trained import load_trained

    env = ApproachGroupEnv(waypoints=True, waypoints_near_group=True)
    core = env.unwrapped
    inside = []
    for at_place in (False, True):
        policy = load_trained("vector", env.observation_space, None,
                              ShieldParams.from_env(core.robot_params, core.social, core.task, at_place))
        ends = []
        for seed in range(500000, 500010):
            r = run_episode(env, policy, seed)
            assert r.metrics["success"] == 1.0
            last = r.trajectory[-1]
            ends.append(float(np.hypot(*(last["members"] - last["robot"][:2]).T).min()))
        inside.append(min(ends))
    assert inside[0] < 1.15 and inside[1] >= 1.18


def test_the_shield_keeps_the_robot_out_of_the_ospace_short_of_the_places_ring():
    """Group centre 1.0 m ahead with an o-space radius of 0.9 m: the robot's centre may come to 0.6 m from it
    (``OSPACE_MARGIN`` 0.3 inside the radius). Full speed at the centre: the closing speed on it is cut to
    sqrt(2 a (d - 0.6)) (0.2 m/s at d = 0.7), the sideways part kept; at 0.6 m only sideways motion is left; away
    from the centre nothing changes; without ``ospace_keep_out`` nothing is braked."""
    from ssbl_pb.core.shield import OSPACE_MARGIN

    keep = ShieldParams(ospace_keep_out=True)
    assert OSPACE_MARGIN == pytest.approx(0.3)
    for d, closing in ((1.2, P.max_speed * 0.6), (0.7, math.sqrt(2 * 0.2 * 0.1)), (0.6, 0.0), (0.5, 0.0)):
        obs = obs_with(np.zeros((0, 2)))
        obs[0], obs[2], obs[4] = 2.0 / POS_SCALE, d / POS_SCALE, 0.9 / POS_SCALE
        out = shield_action(obs, np.array([0.6, 0.8], dtype=np.float32), keep) * P.max_speed
        assert out[0] == pytest.approx(min(closing, P.max_speed * 0.6), abs=1e-4), d
        assert out[1] == pytest.approx(P.max_speed * 0.8, abs=1e-4)
        away = shield_action(obs, np.array([-0.6, 0.8], dtype=np.float32), keep)
        assert away == pytest.approx([-0.6, 0.8], abs=1e-6)
        assert shield_action(obs, np.array([0.6, 0.8], dtype=np.float32), P) == pytest.approx([0.6, 0.8], abs=1e-6)
    with pytest.raises(ConfigError, match="ospace_keep_out"):
        ShieldParams(ospace_keep_out="yes")


def test_kept_out_of_the_ospace_the_shipped_policy_joins_the_pairs_it_lost_inside_it():
    """Closed loop, the shipped policy on `mixed` starts (an L-shaped and a side-by-side pair, held-out seeds)
    where, without the o-space keep-out, it ends inside the o-space 0.3-0.7 m inward of its place until the
    time-out: with it, it joins both and never comes nearer the centre than the radius less 0.3 m (5 cm of
    braking slack)."""
    from ssbl_pb.agents.rollout import run_episode
    from ssbl_pb.agents.trained import load_trained

    env = ApproachGroupEnv(scenario="mixed", waypoints=True, waypoints_near_group=True)
    core = env.unwrapped
    params = ShieldParams.from_env(core.robot_params, core.social, core.task, True)
    for keep, won in ((False, 0.0), (True, 1.0)):
        policy = load_trained("vector", env.observation_space, None,
                              dataclasses.replace(params, ospace_keep_out=keep))
        for seed in (500029, 500123):
            r = run_episode(env, policy, seed)
            assert r.metrics["success"] == won, (keep, seed)
            if keep:
                inner = min(np.hypot(*(s["robot"][:2] - s["centre"])) - s["radius"] for s in r.trajectory)
                assert inner >= -0.35


# -- what the shield changed, and by which rule --------------------------------------------------------------
def test_the_shield_names_the_rule_that_changed_each_action():
    from ssbl_pb.core.observation import BASE_SIZE, SCAN_RANGE
    from ssbl_pb.core.shield import (
        RULE_MEMBERS,
        RULE_OBSTACLES,
        RULE_PLACE,
        RULE_SLIDE,
        shield_actions_explained,
    )

    member = obs_with(np.array([[REACH + 0.28 + 0.6, 0.0]]))  # braked to 0.2 m/s (hand case above)
    speck = obs_with(np.zeros((0, 2)))
    speck[BASE_SIZE:] = 1.0
    speck[BASE_SIZE] = (REACH + P.obstacle_clearance_min) / SCAN_RANGE  # slides along it
    wall = obs_with(np.zeros((0, 2)))
    wall[BASE_SIZE:] = 1.0
    wall[BASE_SIZE] = (REACH + P.obstacle_clearance_min + 0.3) / SCAN_RANGE  # braked, not stopped
    place = obs_with(np.zeros((0, 2)))
    place[0] = 0.5 / POS_SCALE  # the place 0.5 m ahead: the arrival cap binds
    capped = dataclasses.replace(P, place_arrival_speed=0.05)
    obs = np.stack([member, member, speck, wall])
    act = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 0.0]], dtype=np.float32)
    out, rules = shield_actions_explained(obs, act, P)
    assert rules.tolist() == [RULE_MEMBERS, 0, RULE_SLIDE | RULE_OBSTACLES, RULE_OBSTACLES]
    assert out[0, 0] * 0.35 == pytest.approx(math.sqrt(2 * 0.2 * 0.1)) and np.allclose(out[1], act[1])
    out, rules = shield_actions_explained(place[None], np.array([[1.0, 0.0]], dtype=np.float32), capped)
    assert rules.tolist() == [RULE_PLACE] and out[0, 0] < 1.0
    shield = SafetyShield(P)  # the record a policy's shield keeps of its last call
    shield(member, np.array([1.0, 0.0], dtype=np.float32))
    row = shield.last.row()
    assert row["rules"] == ["members"] and row["before"] == [1.0, 0.0] and row["after"][0] < 1.0
    shield(member, np.array([0.0, 1.0], dtype=np.float32))
    assert shield.last.row() is None  # unchanged: nothing to record


def test_the_shield_wrapper_says_what_it_changed_in_info():
    from ssbl_pb.env.gymenv.wrappers import ShieldWrapper

    env = ShieldWrapper(ApproachGroupEnv())
    obs, _ = env.reset(seed=3)
    seen = []
    for _ in range(300):  # full speed toward the place, into the group
        toward = obs[:2] / max(float(np.hypot(*obs[:2])), 1e-6)
        obs, _, terminated, truncated, info = env.step(toward)
        seen.append(info["shield"])
        if terminated or truncated:
            break
    acted = [s for s in seen if s is not None]
    assert acted and len(acted) < len(seen) and all("members" in s["rules"] or "obstacles" in s["rules"]
                                                    for s in acted)


def test_evaluation_reports_the_shield_intervention_rate_the_same_played_alone_or_in_a_batch():
    from ssbl_pb.agents.rollout import run_episode, run_episodes
    from ssbl_pb.analysis.evaluation import Setup

    seeds = list(range(700, 706))
    env, policy = Setup("vector", scenario="mixed", shield=True)()
    single = [run_episode(env, policy, s, keep_trajectory=False) for s in seeds]  # one env, step by step
    batch = run_episodes(Setup("vector", scenario="mixed", shield=True), seeds, workers=1, chunk=len(seeds))
    rates = [r.metrics["shield_intervention_rate"] for r in single]
    assert rates == [r.metrics["shield_intervention_rate"] for r in batch]
    assert all(0.0 <= x < 1.0 for x in rates) and max(rates) > 0.0
    off = run_episodes(Setup("vector", scenario="mixed", shield=False), seeds[:2], workers=1)
    assert [r.metrics["shield_intervention_rate"] for r in off] == [0.0, 0.0]


def test_action_stages_smooth_then_shield_and_reset_rows():
    from ssbl_pb.core.actions import ActionFilter, ActionStages

    core = ApproachGroupEnv()
    obs, _ = core.reset(seed=3)
    params = ShieldParams.from_env(core.robot_params, core.social, core.task)
    stages, ref = ActionStages(0.4, params), ActionFilter(0.4)
    obs = obs.copy()
    obs[MEMBERS + MEMBER_X], obs[MEMBERS + MEMBER_Y] = 0.9 / POS_SCALE, 0.0  # the nearest member 0.9 m ahead
    rows = np.stack([obs, obs])
    for a in (np.array([[1.0, 0.0], [0.5, 0.5]]), np.array([[1.0, 1.0], [-1.0, 0.2]])):
        smoothed = ref(a)
        expected = shield_actions(rows, smoothed, params)  # the filter first, the shield last
        assert not np.array_equal(expected, smoothed)  # the shield brakes toward the member
        assert np.array_equal(stages(rows, a), expected)
    stages.reset(rows=[1])  # row 1's episode starts again: its next action passes the filter unsmoothed
    out = stages(rows, np.array([[0.0, 0.0], [0.3, -0.3]]))
    assert np.allclose(out[1], shield_actions(rows[1:], np.array([[0.3, -0.3]], np.float32), params)[0])
    assert ActionStages(1.0, None)(rows, np.array([[2.0, 0.0]])).tolist() == [[2.0, 0.0]]  # both off: unchanged
    with pytest.raises(UserError, match="action smoothing alpha 0"):
        ActionStages(0.0)


def test_the_shield_builder_and_the_last_stage_perception_takes_over():
    from ssbl_pb.core.actions import ActionStages, take_over

    core = ApproachGroupEnv(robot={"max_speed": 0.3})
    built = ActionStages.of(core, 0.5, shield=True, at_place=True).shield.params
    assert built == ShieldParams.from_env(core.robot_params, core.social, core.task, True) and built.max_speed == 0.3
    assert ActionStages.of(core, shield=False).shield is None
    actions = np.array([[0.4, -0.2, 0.9], [1.0, 1.0, 1.0]])
    body = np.array([[0.15, 0.0], [0.0, 0.06]])  # perception's own command (m/s): a search, a look's sidestep
    out = take_over(actions, np.array([False, True]), body, 0.3)
    assert out.tolist() == [[0.4, -0.2, 0.9], [0.0, 0.2, 0.0]] and actions[1].tolist() == [1.0, 1.0, 1.0]
    assert take_over(actions, np.zeros(2, bool), body, 0.3) is actions  # nobody driven: the policy's, as is


def test_with_the_observation_model_the_rate_counts_the_steps_the_policy_drove_not_those_a_search_replaced():
    from ssbl_pb.agents.rollout import run_episode, run_episodes, shield_rules
    from ssbl_pb.analysis.evaluation import Setup

    setup = Setup("vector", scenario="mixed", env_kwargs=(("perception", True),))
    env, policy = setup()
    sim, seen = env.unwrapped.sim, []
    r = run_episode(env, policy, 500009, keep_trajectory=False,
                    on_step=lambda e: seen.append((bool(sim.driven[0]), int(shield_rules(policy, 1)[0]))))
    steps = seen[1:]  # the first call comes after the reset, before any step
    driven = [rules for d, rules in steps if d]
    assert len(driven) < len(steps)  # it searched for the group, or looked at members, on some steps
    assert r.metrics["shield_intervention_rate"] == pytest.approx(sum(x != 0 for x in driven) / len(driven))
    for name in ("members", "place"):  # each rule's share of the same steps (core.shield.RULES)
        flag = RULES.index(name)
        share = sum(bool(x & (1 << flag)) for x in driven) / len(driven)
        assert r.metrics[f"shield_{name}_rate"] == pytest.approx(share) and share > 0
    rates = [r.metrics[f"shield_{name}_rate"] for name in RULES]
    assert max(rates) <= r.metrics["shield_intervention_rate"] <= sum(rates) + 1e-12  # a step may meet several
    batch = run_episodes(setup, [500009], workers=1)
    assert batch[0].metrics["shield_intervention_rate"] == r.metrics["shield_intervention_rate"]
    assert [batch[0].metrics[f"shield_{n}_rate"] for n in RULES] == rates
