"""Per-episode social metrics from a recorded trajectory (``ApproachGroupEnv(record=True).trajectory``).

Pure functions of arrays. Distances to members are clearances between bodies (Pepper's footprint and the
member's circle), as recorded by the env. Accelerations and jerks are finite differences of the base's
velocity at the control period.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .task import TaskParams

METRIC_KEYS = ("success", "collision", "violation", "time_to_success_s", "episode_time_s", "path_length_m",
               "min_clearance_m", "intimate_zone_time_s", "personal_zone_time_s", "human_displacement_m",
               "mean_accel", "max_accel", "mean_jerk", "max_jerk", "arrival_speed", "outside_fov_time_s",
               "approach_in_fov", "final_slot_error_m", "final_heading_error_deg", "n_humans")


def outside_fov(robot_xy: np.ndarray, members: np.ndarray, members_yaw: np.ndarray, half_angle_deg: float
                ) -> np.ndarray:
    """Whether the robot is outside each member's field of view (bool per member)."""
    d = robot_xy[None, :] - members
    bearing = np.arctan2(d[:, 1], d[:, 0]) - members_yaw
    return np.abs(np.angle(np.exp(1j * bearing))) > math.radians(half_angle_deg)


def episode_metrics(trajectory: list[dict[str, Any]], success: bool, collision: bool, violation: bool,
                    task: TaskParams, dt: float, fov_half_angle_deg: float = 100.0) -> dict[str, float]:
    """All per-episode metrics (see ``METRIC_KEYS``) of one recorded episode."""
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
    return {
        "success": float(success),
        "collision": float(collision),
        "violation": float(violation),
        "time_to_success_s": steps * dt if success else float("nan"),
        "episode_time_s": steps * dt,
        "path_length_m": float(np.hypot(*np.diff(robot[:, :2], axis=0).T).sum()) if steps else 0.0,
        "min_clearance_m": float(clear.min()),
        "intimate_zone_time_s": float((min_clear < task.intimate_zone).sum() * dt),
        "personal_zone_time_s": float((min_clear < task.personal_zone).sum() * dt),
        "human_displacement_m": float(np.hypot(moved[..., 0], moved[..., 1]).sum()) if steps else 0.0,
        "mean_accel": float(acc_n.mean()),
        "max_accel": float(acc_n.max()),
        "mean_jerk": float(jerk_n.mean()),
        "max_jerk": float(jerk_n.max()),
        "arrival_speed": float(np.hypot(*vel[-1])),
        "outside_fov_time_s": outside_time,
        "approach_in_fov": float(outside_time == 0.0),
        "final_slot_error_m": float(np.hypot(*(last["slot"] - last["robot"][:2]))),
        "final_heading_error_deg": heading_err,
        "n_humans": float(members.shape[1]),
    }
