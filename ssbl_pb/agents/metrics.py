"""Per-episode social metrics from a recorded trajectory (``ApproachGroupEnv(record=True).trajectory``).

Pure functions of arrays. Distances to members are clearances between bodies (Pepper's footprint and the
member's circle), as recorded by the env. Accelerations and jerks are finite differences of the base's
velocity at the control period. ``METRICS`` gives every metric's unit, direction and the name the community
uses for it (Francis et al. 2023, Table 1; SocNavGym; HuNavSim's evaluator); docs/metrics.md is its long form.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.reward import route_distance
from ..core.task import TaskParams

# name: (unit, direction: "lower" / "higher" is better or "" descriptive, community name)
METRICS: dict[str, tuple[str, str, str]] = {
    "success": ("0/1", "higher", "Success (S)"),
    "collision": ("0/1", "lower", "Collision (C): human (HC) and wall (WC) collisions"),
    "obstacle_collision": ("0/1", "lower", "Collision (C) with a wall or an obstacle (WC)"),
    "violation": ("0/1", "lower", "intimate-space violation (collision included); HuNavSim intimate intrusions"),
    "timeout": ("0/1", "lower", "Timeout (TO)"),
    "time_to_success_s": ("s", "lower", "Time (T) / time to reach goal"),
    "episode_time_s": ("s", "lower", "episode duration"),
    "path_length_m": ("m", "lower", "Path length (PL)"),
    "spl": ("0-1", "higher", "Success weighted by Path Length (SPL)"),
    "min_clearance_m": ("m", "higher", "Minimum distance to human (DH min) / clearing distance, between bodies"),
    "min_wall_clearance_m": ("m", "higher", "Clearing distance (CD min) to the walls"),
    "min_obstacle_clearance_m": ("m", "higher", "Clearing distance (CD min) to walls and obstacles"),
    "min_ttc_s": ("s", "higher", "Minimum time to collision (TTC)"),
    "intimate_zone_time_s": ("s", "lower", "intimate space intrusions (HuNavSim), as time"),
    "personal_zone_time_s": ("s", "lower", "Space compliance (SC) / personal space intrusions, as time"),
    "ospace_intrusion_time_s": ("s", "lower", "interaction (o-)space intrusions (HuNavSim IS_prox; Okal & Arras)"),
    "human_displacement_m": ("m", "lower", "members' path length caused (SocNavBench-style displacement)"),
    "social_work": ("force x s", "lower", "Social work (HuNavSim: W_r + sum W_p)"),
    "speed_min": ("m/s", "", "Velocity (V min)"),
    "speed_mean": ("m/s", "", "Velocity (V avg)"),
    "speed_max": ("m/s", "", "Velocity (V max)"),
    "stalled_time_s": ("s", "lower", "Stalled time (ST) / time not moving"),
    "mean_accel": ("m/s^2", "lower", "Acceleration (A avg)"),
    "max_accel": ("m/s^2", "lower", "Acceleration (A max)"),
    "mean_jerk": ("m/s^3", "lower", "Jerk (J avg)"),
    "max_jerk": ("m/s^3", "lower", "Jerk (J max)"),
    "arrival_speed": ("m/s", "lower", "speed on arrival (approach-specific)"),
    "outside_fov_time_s": ("s", "lower", "time approaching outside a member's view (approach-specific)"),
    "approach_in_fov": ("0/1", "higher", "approached in view throughout (approach-specific)"),
    "final_slot_error_m": ("m", "lower", "Final distance to target (SEAN)"),
    "final_heading_error_deg": ("deg", "lower", "final heading error to the group centre"),
    "n_humans": ("count", "", "group size (descriptive)"),
}
# with the observation model on, where perception left the episode (``BatchedApproach.perceived_outcome``)
PERCEIVED_METRICS: dict[str, tuple[str, str, str]] = {
    "perceived_slot_error_m": ("m", "lower", "the perceived place's distance from the true one at the end"),
    "perceived_place_distance_m": ("m", "lower", "the robot's distance from the place it perceived at the end"),
    "members_unfound": ("count", "lower", "true members perception never knew at the end"),
}
METRIC_KEYS = tuple(METRICS)
LOWER_IS_BETTER = {k for k, v in METRICS.items() if v[1] == "lower"}
HIGHER_IS_BETTER = {k for k, v in METRICS.items() if v[1] == "higher"}
STALL_SPEED = 0.05  # m/s: below it the robot counts as stalled (ours: half the success rule's stop speed)
TTC_HORIZON = 10.0  # s: time to collision is reported up to this (a third of an episode); none ahead = horizon


def time_to_collision(rel_pos: np.ndarray, rel_vel: np.ndarray, radius: float, horizon: float = TTC_HORIZON
                      ) -> np.ndarray:
    """Seconds until discs ``radius`` apart in centre distance touch at constant velocities (rows: pairs of
    relative position and velocity (k, 2), member minus robot); 0 when touching, ``horizon`` when never within it."""
    b = (rel_pos * rel_vel).sum(axis=-1)
    a = (rel_vel * rel_vel).sum(axis=-1)
    c = (rel_pos * rel_pos).sum(axis=-1) - radius * radius
    disc = b * b - a * c
    closing = (b < 0) & (disc >= 0) & (a > 1e-12)
    t = np.where(closing, (-b - np.sqrt(np.maximum(disc, 0.0))) / np.where(a > 1e-12, a, 1.0), horizon)
    return np.clip(np.where(c <= 0, 0.0, t), 0.0, horizon)


def outside_fov(robot_xy: np.ndarray, members: np.ndarray, members_yaw: np.ndarray, half_angle_deg: float
                ) -> np.ndarray:
    """Whether the robot is outside each member's field of view (bool per member)."""
    d = robot_xy[None, :] - members
    bearing = np.arctan2(d[:, 1], d[:, 0]) - members_yaw
    return np.abs(np.angle(np.exp(1j * bearing))) > math.radians(half_angle_deg)


def episode_metrics(trajectory: list[dict[str, Any]], success: bool, collision: bool, violation: bool,
                    task: TaskParams, dt: float, fov_half_angle_deg: float = 100.0, contact_radius: float = 0.5075,
                    obstacle_collision: bool = False) -> dict[str, float]:
    """All per-episode metrics (see ``METRICS``) of one recorded episode; ``contact_radius`` is the centre
    distance at which robot and member touch for the time to collision (body radii, 0.28 + 0.2275 m);
    ``obstacle_collision``: the collision was with a wall or an obstacle."""
    robot = np.array([s["robot"] for s in trajectory])
    vel = np.array([s["robot_vel"][:2] for s in trajectory])
    members = np.array([s["members"] for s in trajectory])  # (T+1, n, 2)
    clear = np.array([s["clearance"] for s in trajectory])  # (T+1, n)
    steps = len(trajectory) - 1
    min_clear = clear.min(axis=1)[1:]
    acc = np.diff(vel, axis=0) / dt
    acc_n = np.hypot(acc[:, 0], acc[:, 1]) if len(acc) else np.zeros(1)
    jerk = np.diff(acc, axis=0) / dt
    jerk_n = np.hypot(jerk[:, 0], jerk[:, 1]) if len(jerk) else np.zeros(1)
    social = clear[1:] < task.social_zone
    fov = np.array([outside_fov(s["robot"][:2], s["members"], s["members_yaw"], fov_half_angle_deg)
                    for s in trajectory[1:]]) if steps else np.zeros((0, clear.shape[1]), dtype=bool)
    outside_time = float(np.any(fov & social, axis=1).sum() * dt) if steps else 0.0
    last = trajectory[-1]
    to_c = last["centre"] - last["robot"][:2]
    heading_err = math.degrees(abs(math.remainder(math.atan2(to_c[1], to_c[0]) - last["robot"][2], 2 * math.pi)))
    moved = np.diff(members, axis=0)
    speed = np.hypot(vel[1:, 0], vel[1:, 1]) if steps else np.zeros(1)
    slot_dist = np.array([math.dist(s["slot"].tolist(), s["robot"][:2].tolist()) for s in trajectory[1:]])
    to_centre = np.array([math.dist(s["centre"].tolist(), s["robot"][:2].tolist()) for s in trajectory[1:]])
    radius = np.array([s["radius"] for s in trajectory[1:]])
    away = slot_dist >= task.slot_tolerance  # not yet at its place
    first = trajectory[0]
    if "keep_out" in first:  # the shortest way to where it joined, around the group (reward.route_distance)
        shortest = route_distance(first["robot"][:2], last["slot"], first["centre"], first["keep_out"])
    else:
        shortest = math.dist(first["robot"][:2].tolist(), last["slot"].tolist())
    path = float(np.hypot(*np.diff(robot[:, :2], axis=0).T).sum()) if steps else 0.0
    ttc = TTC_HORIZON
    if steps:
        rel = members[1:] - robot[1:, None, :2]
        rel_v = moved / dt - vel[1:, None, :]
        ttc = float(time_to_collision(rel.reshape(-1, 2), rel_v.reshape(-1, 2), contact_radius).min())
    social = [s.get("social_force", 0.0) for s in trajectory[1:]]
    return {
        "success": float(success),
        "collision": float(collision),
        "obstacle_collision": float(obstacle_collision),
        "violation": float(violation),
        "timeout": float(not success and not violation),
        "time_to_success_s": steps * dt if success else float("nan"),
        "episode_time_s": steps * dt,
        "path_length_m": path,
        "spl": float(success) * shortest / max(path, shortest, 1e-9),
        "min_clearance_m": float(clear.min()),
        "min_wall_clearance_m": float(min(s.get("wall", math.inf) for s in trajectory)),
        "min_obstacle_clearance_m": float(min(s.get("obstacle", s.get("wall", math.inf)) for s in trajectory)),
        "min_ttc_s": ttc,
        "intimate_zone_time_s": float((min_clear < task.intimate_zone).sum() * dt),
        "personal_zone_time_s": float((min_clear < task.personal_zone).sum() * dt),
        "ospace_intrusion_time_s": float(((to_centre < radius) & away).sum() * dt),
        "human_displacement_m": float(np.hypot(moved[..., 0], moved[..., 1]).sum()) if steps else 0.0,
        "social_work": float(np.sum(social) * dt),
        "speed_min": float(speed.min()),
        "speed_mean": float(speed.mean()),
        "speed_max": float(speed.max()),
        "stalled_time_s": float(((speed < STALL_SPEED) & away).sum() * dt) if steps else 0.0,
        "mean_accel": float(acc_n.mean()),
        "max_accel": float(acc_n.max()),
        "mean_jerk": float(jerk_n.mean()),
        "max_jerk": float(jerk_n.max()),
        "arrival_speed": float(np.hypot(*vel[-1])) if success else float("nan"),  # no arrival: none
        "outside_fov_time_s": outside_time,
        "approach_in_fov": float(outside_time == 0.0),
        "final_slot_error_m": float(np.hypot(*(last["slot"] - last["robot"][:2]))),
        "final_heading_error_deg": heading_err,
        "n_humans": float(members.shape[1]),
    }


# why an episode through the observation model failed (``failure_kind``), in the order they are checked
FAILURE_KINDS = ("violation", "wrong place", "short", "near")
# the place is "off" beyond this many slot tolerances: at the end of the shipped policy's failed `mixed` episodes
# through the MoveNet model, perceived-place errors and the robot's distances from that place lay either within
# 0.7 m or beyond 1.0 m (33 failures of 200, commit ed734f5), 2 x 0.3 m between the two
OFF_TOLERANCES = 2.0


def failure_kind(success: bool, violation: bool, slot_error: float, place_distance: float, tolerance: float) -> str:
    """Why an episode run through the observation model failed ("" when it joined): ``violation`` (a collision
    or an intimate-zone entry); ``wrong place``: the place it perceived (``slot_error`` m from the true one) lies
    further than ``OFF_TOLERANCES`` slot tolerances off (a member never found, the wrong gap, too few people known);
    ``short``: the robot ended further than that from the place it perceived (``place_distance``; held back,
    rounding the group, still searching); ``near``: at a place perceived about right (the estimate's last
    centimetres, or not stopped and facing the centre in time)."""
    if success:
        return ""
    if violation:
        return "violation"
    off = OFF_TOLERANCES * tolerance
    if not slot_error <= off:
        return "wrong place"
    return "short" if not place_distance <= off else "near"


def failure_counts(rows: list[dict[str, float]], tolerance: float) -> dict[str, int]:
    """How many of the episodes ``rows`` (with the ``PERCEIVED_METRICS``) failed each way (``FAILURE_KINDS``)."""
    kinds = [failure_kind(bool(r["success"]), bool(r["violation"]), r["perceived_slot_error_m"],
                          r["perceived_place_distance_m"], tolerance) for r in rows]
    return {k: kinds.count(k) for k in FAILURE_KINDS}
