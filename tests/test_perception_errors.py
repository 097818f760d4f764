"""Perception's errors against ground truth (bench/perception_errors.py): small synthetic logs with errors computed
by hand, and a lockstep run whose rebuilt observations are the ones the policy saw."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.bench.perception_errors import (
    ErrorParams,
    analyse,
    assign,
    markdown_table,
    match_ticks,
    observation,
    pool,
    summarise,
    view_class,
)
from ssbl_pb.bench.perception_errors_plot import plot
from ssbl_pb.deploy.frames import transform_points
from ssbl_pb.deploy.robot import compose
from ssbl_pb.params import RobotParams

START = np.array([1.0, 2.0, math.pi / 2])  # the robot's start pose in the room: the odometry frame's origin


def room(xy) -> list:
    """Odometry-frame points to the room frame (the virtual Pepper logs the room frame)."""
    return transform_points(START, np.asarray(xy, dtype=float)).tolist()


def state(wall, members, pose=(0.0, 0.0, 0.0), member_vel=None, centre=(3.0, 0.0), slot=(2.0, 0.5), radius=0.8):
    """A virtual Pepper state row; ``pose``, ``members``, ``centre``, ``slot`` given in the odometry frame,
    ``member_vel`` in the room frame."""
    members = np.asarray(members, dtype=float).reshape(-1, 2)
    return {"kind": "state", "wall": wall, "pose": compose(START, np.asarray(pose, dtype=float)).tolist(),
            "odom": list(pose), "vel": [0.0, 0.0, 0.0], "members": room(members),
            "member_vel": np.zeros_like(members).tolist() if member_vel is None else member_vel,
            "centre": room([centre])[0], "slot": room([slot])[0], "radius": radius, "clearance": 1.0,
            "collision": False}


def tick(wall, tracks, pose=(0.0, 0.0, 0.0), group=None):
    """A deploy tick row; ``tracks``: (id, x, y[, vx, vy[, seen]]) in the odometry frame; ``group``: (centre,
    radius, slot) on a policy tick."""
    humans = []
    for t in tracks:
        tid, x, y, *rest = t
        vx, vy, seen = (list(rest) + [0.0, 0.0, True][len(rest):])[:3]
        humans.append({"id": tid, "x": x, "y": y, "vx": vx, "vy": vy, "seen": seen})
    row = {"t": wall, "wall": wall, "state": "approach", "odom_x": pose[0], "odom_y": pose[1], "odom_yaw": pose[2],
           "room_pose": list(pose), "vel": [0.0, 0.0, 0.0], "humans": humans, "tick_ms": 0.0, "odom_ms": 0.0}
    if group is not None:
        row.update(centre=list(group[0]), radius=group[1], slot=list(group[2]))
    return row


def run(rows, states, **kw):
    return summarise(analyse(rows, {"start_pose": START.tolist()}, states, **kw))


def test_a_track_0_2_m_off_a_member_2_m_ahead_is_0_2_m_wrong_at_2_m():
    r = run([tick(1.0, [(1, 2.0, 0.2)])], [state(1.0, [[2.0, 0.0]])])
    assert r["position_error_m"]["seen"]["median"] == pytest.approx(0.2)
    (bin_2m,) = [b for b in r["position_error_by_distance"] if b["lo"] == 2.0]
    assert bin_2m["n"] == 1 and bin_2m["median"] == pytest.approx(0.2)
    assert sum(b["n"] for b in r["position_error_by_distance"]) == 1
    assert r["missed"]["count"] == 0 and r["duplicated_member_ticks"] == 0 and r["false_tracks"] == 0


def test_the_robot_s_own_pose_turns_the_truth_into_its_view():
    # the robot stands at (1, 1) facing +y in the odometry frame: a member at (1, 3) is 2 m straight ahead
    rng, bearing, cls = view_class(np.array([1.0, 1.0, math.pi / 2]), np.array([[1.0, 3.0], [3.0, 1.0]]))
    assert rng[0] == pytest.approx(2.0) and bearing[0] == pytest.approx(0.0, abs=1e-9) and cls[0] == 0
    assert bearing[1] < -80 and cls[1] == 3  # to its right: out of view


def test_members_are_missed_out_of_view_occluded_or_in_view():
    at = lambda rng, deg: [rng * math.cos(math.radians(deg)), rng * math.sin(math.radians(deg))]  # noqa: E731
    members = [at(3.0, 40.0), at(2.0, 0.0), at(3.5, 0.0), at(3.0, -15.0), at(1.1, 22.0)]
    _, _, cls = view_class(np.zeros(3), np.array(members))
    # 40 deg is outside the camera's 56 deg; right behind another member is occluded; 15 deg is in view; 1.1 m at
    # 22 deg: its centre is in view, its side (0.23 m, 12 deg) is not
    assert [["in_view", "edge", "occluded", "out_of_view"][c] for c in cls] == [
        "out_of_view", "in_view", "occluded", "in_view", "edge"]
    r = run([tick(1.0, [(7, *members[1])])], [state(1.0, members)])
    assert r["missed"] == {"count": 4, "rate": pytest.approx(0.8), "in_view": 1, "edge": 1, "occluded": 1,
                           "out_of_view": 1}
    assert r["by_view"]["in_view"]["missed_rate"] == pytest.approx(0.5)


def test_two_tracks_on_one_member_are_one_duplicate_and_a_track_far_from_everyone_is_false():
    r = run([tick(1.0, [(1, 2.0, 0.1), (2, 2.1, -0.1), (3, 4.0, 3.0)])], [state(1.0, [[2.0, 0.0], [2.5, 1.5]])])
    assert r["duplicated_member_ticks"] == 1 and r["duplicate_tracks"] == 1 and r["false_tracks"] == 1
    assert r["missed"]["count"] == 1  # the second member has no track within the gate
    assert r["position_error_m"]["seen"]["median"] == pytest.approx(0.1)  # the nearer of the two is its track


def test_the_hungarian_assignment_gives_each_member_its_own_track():
    primary, owner = assign(np.array([[0.0, 0.3], [0.0, 0.9]]), np.array([[0.0, 0.0], [0.0, 0.6]]), 0.75)
    assert primary.tolist() == [0, 1] and owner.tolist() == [0, 1]  # not both on the nearest member
    primary, owner = assign(np.array([[0.0, 0.0], [5.0, 5.0]]), np.array([[0.0, 0.1]]), 0.75)
    assert primary.tolist() == [0] and owner.tolist() == [0, -1]


def test_a_member_who_comes_back_under_a_new_id_has_two_ids():
    member = [[2.0, 0.0]]
    rows = [tick(1.0, [(1, 2.0, 0.0)]), tick(1.1, []), tick(1.2, [(5, 2.0, 0.05)]), tick(1.3, [(5, 2.0, 0.0)])]
    r = run(rows, [state(w, member) for w in (1.0, 1.1, 1.2, 1.3)])
    assert r["ids_per_member"] == {"mean": 2.0, "max": 2, "members": 1, "new_ids": 1}
    assert r["id_switches"] == 1 and r["missed"]["count"] == 1


def test_velocity_errors_compare_in_the_odometry_frame_and_remembered_tracks_apart():
    # the odometry frame is turned 90 deg in the room: a room-frame velocity (0, 0.5) is (0.5, 0) in odometry
    rows = [tick(1.0, [(1, 2.0, 0.0, 0.5, 0.0), (2, 2.0, 1.0, 0.0, 0.3, False)])]
    r = run(rows, [state(1.0, [[2.0, 0.0], [2.0, 1.0]], member_vel=[[0.0, 0.5], [0.0, 0.0]])])
    assert r["velocity_error_mps"]["seen"]["median"] == pytest.approx(0.0, abs=1e-9)
    assert r["velocity_error_mps"]["remembered"]["median"] == pytest.approx(0.3)
    assert r["position_error_m"]["remembered"]["n"] == 1 and r["position_error_m"]["seen"]["n"] == 1


def test_group_errors_compare_deploy_s_estimate_with_the_truth():
    rows = [tick(1.0, [(1, 2.0, 0.0)], group=((3.1, 0.0), 0.9, (2.0, 0.8))), tick(1.1, [(1, 2.0, 0.0)])]
    r = run(rows, [state(w, [[2.0, 0.0]], centre=(3.0, 0.0), slot=(2.0, 0.5), radius=0.8) for w in (1.0, 1.1)])
    assert r["centre_error_m"]["median"] == pytest.approx(0.1) and r["centre_error_m"]["n"] == 1
    assert r["slot_error_m"]["median"] == pytest.approx(0.3)
    assert r["radius_error_m"]["median"] == pytest.approx(0.1) and r["radius_error_m"]["bias"] == pytest.approx(0.1)


def test_ticks_are_matched_to_the_nearest_state_in_wall_time():
    states = [state(w, [[2.0, 0.0]]) for w in (10.0, 10.02, 10.04)]
    row = tick(10.05, [])
    row.update(tick_ms=31.0, odom_ms=2.0)  # odometry was read 29 ms before the row was written: 10.021
    (pair,) = match_ticks([row], states)
    assert pair[1]["wall"] == 10.02
    assert match_ticks([tick(11.0, [])], states) == []  # no state within 0.1 s: skipped


class SlotPolicy:
    """A stand-in network: its action is the observation's slot entries (approach frame, / 5 m)."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.asarray(obs[:2], dtype=float), None


def test_the_action_difference_is_the_policy_on_the_perceived_minus_on_the_true_observation():
    # deploy put the slot 0.5 m too far along the approach (+x: the centre is straight ahead): 0.1 in the action
    row = tick(1.0, [(1, 3.0, 0.8)], group=((3.0, 0.0), 0.8, (2.5, 0.0)))
    s = analyse([row], {"start_pose": START.tolist()}, [state(1.0, [[3.0, 0.8]], centre=(3.0, 0.0), slot=(2.0, 0.0))],
                policy=SlotPolicy())
    assert np.asarray(s.action_delta) == pytest.approx(np.array([[0.1, 0.0]]), abs=1e-6)
    r = summarise(s)
    assert r["action_delta"]["ticks"] == 1 and r["action_delta"]["mean"] == pytest.approx(0.1, abs=1e-6)
    assert r["action_delta_still"]["mean"] == pytest.approx(0.1, abs=1e-6)  # nobody moves: the same


def test_members_velocities_are_zeroed_in_both_observations_for_the_still_difference():
    class VelocityPolicy:  # acts on the nearest member's velocity entries only
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.asarray(obs[16:18], dtype=float), None

    row = tick(1.0, [(1, 3.0, 0.8, 0.0, 0.2)], group=((3.0, 0.0), 0.8, (2.0, 0.0)))
    s = analyse([row], {"start_pose": START.tolist()}, [state(1.0, [[3.0, 0.8]], centre=(3.0, 0.0), slot=(2.0, 0.0))],
                policy=VelocityPolicy())
    assert np.asarray(s.action_delta) == pytest.approx(np.array([[0.0, 0.2]]), abs=1e-6)
    assert np.asarray(s.action_delta_still) == pytest.approx(np.zeros((1, 2)), abs=1e-9)


def test_summaries_pool_runs_and_make_a_table_and_a_figure(tmp_path):
    a = analyse([tick(1.0, [(1, 2.0, 0.2)])], {"start_pose": START.tolist()}, [state(1.0, [[2.0, 0.0]])])
    b = analyse([tick(1.0, [(1, 4.0, 0.4)])], {"start_pose": START.tolist()}, [state(1.0, [[4.0, 0.0]])])
    total = summarise(pool([a, b]))
    assert total["member_ticks"] == 2 and total["position_error_m"]["seen"]["median"] == pytest.approx(0.3)
    assert total["ids_per_member"]["members"] == 2
    table = markdown_table([{"seed": 3, "perception": summarise(a)}, {"seed": 4, "perception": None}], total)
    assert table.count("\n") == 4 and "| 3 | 0.20 / 0.20 |" in table and "| all |" in table
    out = plot(pool([a, b]), tmp_path / "errors.png")
    assert out.stat().st_size > 10_000


def test_gate_and_field_of_view_are_parameters():
    r = run([tick(1.0, [(1, 2.0, 0.5)])], [state(1.0, [[2.0, 0.0]])], p=ErrorParams(gate_m=0.4))
    assert r["missed"]["count"] == 1 and r["false_tracks"] == 1
    _, _, cls = view_class(np.zeros(3), np.array([[3.0, 1.5]]), ErrorParams(hfov_deg=90.0))
    assert cls[0] == 0  # 27 deg: inside a 90 deg camera


# -- the observations deploy fed its policy --------------------------------------------------------------------
def test_observations_rebuilt_from_the_log_are_the_ones_the_policy_saw(tmp_path):
    from ssbl_pb.bench.deploy import lockstep_approach
    from ssbl_pb.deploy.log import read_log

    class Recording:
        seen: list = []

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            self.seen.append(np.array(obs))
            return np.array([0.6, 0.0]), None

    policy = Recording()
    res = lockstep_approach(tmp_path, 11, policy, "default", duration=6.0)
    assert res["outcome"] == "duration" and policy.seen
    from ssbl_pb.bench.perception_errors import deploy_frames

    rows = [r for r in read_log(tmp_path / "deploy") if r.get("centre") is not None]
    assert len(rows) == len(policy.seen)
    fr = deploy_frames(tmp_path / "deploy", read_log(tmp_path / "deploy"))  # the room's map, as deploy had it
    assert fr.room is not None and fr.walls(fr.room_pose(np.zeros(3))).min() < 4.0  # a wall nearer than none
    for row, obs in zip(rows, policy.seen, strict=True):
        xy = np.array([[h["x"], h["y"]] for h in row["humans"]])
        vel = np.array([[h["vx"], h["vy"]] for h in row["humans"]])
        rebuilt = observation(fr, np.array([row["odom_x"], row["odom_y"], row["odom_yaw"]]), np.array(row["vel"]),
                              xy, vel, np.array(row["centre"]), row["radius"], np.array(row["slot"]), RobotParams())
        assert rebuilt == pytest.approx(obs, abs=1e-5)
    from ssbl_pb.bench.perception_errors import analyse_folder

    s = analyse_folder(tmp_path)
    r = summarise(s)
    assert r["ticks"] == len(read_log(tmp_path / "deploy"))  # each tick has its truth, logged at its time
    clear = np.array(s.view) == 0  # in clear view (the other member of this pair is half hidden behind it)
    assert np.nanmedian(np.array(s.pos_err)[clear]) < 0.1 and r["ids_per_member"]["max"] == 1


def test_each_member_tick_keeps_its_tracks_range_bearing_and_facing_error_for_the_observation_model():
    from ssbl_pb.bench.perception_errors import Samples  # noqa: F401 (the fields under test)

    # a member 2 m ahead facing the robot (yaw pi in the odometry frame) tracked at 2.1 m, 0.1 m to the left,
    # with its facing 10 deg off; a second member 3 m ahead with its back to the robot, 1 m to the right, untracked
    rows = [tick(1.0, [(1, 2.1, 0.1)])]
    rows[0]["humans"][0]["facing"] = math.pi - math.radians(10.0)
    st = state(1.0, [[2.0, 0.0], [3.0, -1.0]])
    st["member_yaw"] = [math.pi + float(START[2]), 0.0 + float(START[2])]  # the room frame
    s = analyse(rows, {"start_pose": START.tolist()}, [st])
    assert s.range_err[0] == pytest.approx(math.hypot(2.1, 0.1) - 2.0)
    assert s.bearing_err[0] == pytest.approx(math.degrees(math.atan2(0.1, 2.1)))
    assert s.facing_err[0] == pytest.approx(-10.0) and s.front == [True, False]
    assert math.isnan(s.range_err[1]) and math.isnan(s.facing_err[1])
    assert s.hidden == [0.0, 0.0] and s.in_image[0] == 1.0 and 0.0 < s.in_image[1] <= 1.0
