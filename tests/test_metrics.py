"""The per-episode metrics against hand computations (agents/metrics.py, docs/metrics.md)."""

import math

import numpy as np
import pytest

from ssbl_pb.agents.metrics import METRICS, PERCEIVED_METRICS, TTC_HORIZON, episode_metrics, time_to_collision
from ssbl_pb.agents.policies import make_policy
from ssbl_pb.agents.rollout import run_episode
from ssbl_pb.core.task import TaskParams
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv

TASK = TaskParams()


def test_time_to_collision_by_hand():
    rel = np.array([[2.0, 0.0], [2.0, 0.0], [0.3, 0.0], [2.0, 1.0]])
    vel = np.array([[-0.5, 0.0], [0.5, 0.0], [0.0, 0.0], [-0.5, 0.0]])
    t = time_to_collision(rel, vel, 0.5)
    assert t[0] == pytest.approx((2.0 - 0.5) / 0.5)  # head on: the gap over the closing speed
    assert t[1] == TTC_HORIZON  # moving apart: never
    assert t[2] == 0.0  # already touching
    assert t[3] == TTC_HORIZON  # passes 1 m to the side of a 0.5 m contact distance


def snapshot(t, x, v, social=0.0):
    """The robot on the x axis at ``x`` moving at ``v`` (m/s), a member at (4, 0) standing still, the group's
    centre at (4.5, 0) with a 0.4 m o-space, the slot at (3, 1)."""
    return {"t": t, "robot": np.array([x, 0.0, 0.0]), "robot_vel": np.array([v, 0.0, 0.0]),
            "members": np.array([[4.0, 0.0]]), "members_yaw": np.array([math.pi]), "centre": np.array([4.5, 0.0]),
            "radius": 0.4, "slot": np.array([3.0, 1.0]), "clearance": np.array([4.0 - x - 0.52]),
            "wall": 5.0 - x, "social_force": social}


def test_metrics_of_a_hand_made_episode():
    dt = 0.1
    # 10 steps at 0.5 m/s from x = 0, then 5 stalled steps at x = 0.5, then 5 steps at 1.0 m/s
    xs, vs = [0.0], [0.0]
    for k in range(20):
        v = 0.5 if k < 10 else (0.0 if k < 15 else 1.0)
        vs.append(v)
        xs.append(xs[-1] + v * dt)
    traj = [snapshot(k * dt, x, v, social=0.2) for k, (x, v) in enumerate(zip(xs, vs, strict=True))]
    m = episode_metrics(traj, False, False, False, TASK, dt, contact_radius=0.5)
    assert set(m) == set(METRICS)
    assert m["timeout"] == 1.0 and m["spl"] == 0.0  # neither success nor violation: time ran out
    assert m["path_length_m"] == pytest.approx(1.0)
    assert (m["speed_min"], m["speed_max"]) == (0.0, 1.0) and m["speed_mean"] == pytest.approx(10 / 20)
    assert m["stalled_time_s"] == pytest.approx(0.5)
    assert m["min_wall_clearance_m"] == pytest.approx(4.0)
    # closest approach to collision: at 1 m/s, 3.0 m from the member, 2.5 m of gap to close
    assert m["min_ttc_s"] == pytest.approx(2.5)
    assert m["social_work"] == pytest.approx(20 * 0.2 * dt)
    assert m["ospace_intrusion_time_s"] == 0.0
    assert math.isnan(m["arrival_speed"])  # it never arrived
    # the same run, joined: SPL is the shortest way (around the keep-out disc) over the path driven
    traj[0]["keep_out"] = 0.5
    traj[-1]["slot"] = np.array([1.0, 0.0])
    win = episode_metrics(traj, True, False, False, TASK, dt)
    assert win["timeout"] == 0.0 and win["spl"] == pytest.approx(1.0 / 1.0)
    assert win["arrival_speed"] == pytest.approx(1.0)  # the last step's speed
    traj[-1]["slot"] = np.array([0.8, 0.0])  # it overshot its place by 0.2 m
    assert episode_metrics(traj, True, False, False, TASK, dt)["spl"] == pytest.approx(0.8)


def test_ospace_intrusion_counts_crossing_the_group_not_standing_at_the_place():
    dt = 0.1
    traj = [snapshot(0.0, 4.3, 0.0)] + [snapshot(0.1 * k, 4.3, 0.0) for k in range(1, 4)]  # 0.2 m from centre
    assert episode_metrics(traj, False, False, False, TASK, dt)["ospace_intrusion_time_s"] == pytest.approx(0.3)
    for s in traj:
        s["slot"] = np.array([4.3, 0.1])  # its place is right there: being there is joining, not intruding
    assert episode_metrics(traj, False, False, False, TASK, dt)["ospace_intrusion_time_s"] == 0.0


def test_every_metric_has_a_documented_direction_and_name():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "metrics.md").read_text()
    for name, (unit, direction, community) in (METRICS | PERCEIVED_METRICS).items():
        assert direction in ("lower", "higher", "") and unit and community
        assert f"`{name}`" in doc, name


def test_episode_metrics_of_two_policies():
    env = ApproachGroupEnv(record=True)
    m = run_episode(env, make_policy("sffm"), 2000).metrics
    env.close()
    assert m["success"] == 1.0 and 0.5 < m["spl"] <= 1.0
    assert m["speed_max"] <= 0.35 + 1e-9 and m["speed_min"] <= m["speed_mean"] <= m["speed_max"]
    assert 0 < m["min_ttc_s"] < TTC_HORIZON and m["min_wall_clearance_m"] > 0
    assert m["social_work"] == 0.0  # it stayed outside every member's SFFM personal zone (1.2 m)
    # a straight line from behind a member cuts into the group: repulsion, and a collision course
    env = ApproachGroupEnv(record=True, scenario="behind")
    m = run_episode(env, make_policy("straight"), 2000).metrics
    env.close()
    assert m["violation"] == 1.0 and m["social_work"] > 0.0 and m["min_ttc_s"] < 2.0 and m["spl"] == 0.0
