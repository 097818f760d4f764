"""The base-dynamics log: reading and validating it, measured body velocities, and synthetic logs.

Format (CSV with a header row, one row per control tick, any extra columns ignored; or JSONL, one object per
tick with the same names, as ``python -m ssbl_pb.deploy`` writes its ``log.jsonl``):

* ``t``: time in seconds, strictly increasing (near-uniform spacing; 10-50 Hz is fine).
* ``cmd_vx``, ``cmd_vy``, ``cmd_wz``: the body-frame velocity command sent at ``t`` (forward m/s, left m/s,
  turn rad/s), held until the next row.
* and either ``odom_x``, ``odom_y``, ``odom_yaw`` (odometry pose at ``t``, world frame, metres and radians),
  or ``odom_vx``, ``odom_vy``, ``odom_wz`` (measured body-frame velocity at ``t``).

Excite one axis at a time (``excitation_plan``): the base couples vx and vy through the planar speed and
acceleration norms, and the per-axis fit assumes the other axes are still.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ..core.base import HolonomicBase
from ..files import write_text
from ..params import CalibrationError, RobotParams

CMD = ("cmd_vx", "cmd_vy", "cmd_wz")
POSE = ("odom_x", "odom_y", "odom_yaw")
VEL = ("odom_vx", "odom_vy", "odom_wz")
AXES = ("vx", "vy", "wz")


@dataclasses.dataclass
class DynamicsLog:
    """Times (N,), commands (N, 3), measured body velocity (N, 3) and how it was measured."""

    t: np.ndarray
    cmd: np.ndarray
    vel: np.ndarray
    from_pose: bool  # True: ``vel`` is a central difference of poses (mean over [t_{i-1}, t_{i+1}])
    path: str = "log"

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t)))


def body_velocity_from_pose(t: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Central-difference body-frame velocity (N, 3) from world poses (N, 3); ends use one-sided differences."""
    yaw = np.unwrap(pose[:, 2])
    xy = pose[:, :2]
    n = len(t)
    i0 = np.clip(np.arange(n) - 1, 0, n - 1)
    i1 = np.clip(np.arange(n) + 1, 0, n - 1)
    span = t[i1] - t[i0]
    dxy = (xy[i1] - xy[i0]) / span[:, None]
    c, s = np.cos(yaw), np.sin(yaw)
    fwd = c * dxy[:, 0] + s * dxy[:, 1]
    left = -s * dxy[:, 0] + c * dxy[:, 1]
    return np.stack([fwd, left, (yaw[i1] - yaw[i0]) / span], axis=1)


def read_log(path: str | Path) -> DynamicsLog:
    """Read and validate a log; ``CalibrationError`` names the file, the column or the row."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: file not found")
    try:
        if path.suffix == ".jsonl":  # a deploy log (ssbl_pb.deploy.log): one object per tick, the same names
            rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
            header = list(rows[0]) if rows else []
        else:
            with path.open(newline="") as fh:
                reader = csv.DictReader(fh)
                header = [h.strip() for h in (reader.fieldnames or [])]
                rows = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error, json.JSONDecodeError) as exc:
        raise CalibrationError(f"{path}: not a readable CSV or JSONL file ({exc})") from exc
    need = ("t",) + CMD
    missing = [c for c in need if c not in header]
    has_pose, has_vel = all(c in header for c in POSE), all(c in header for c in VEL)
    if missing or not (has_pose or has_vel):
        odo = [] if has_pose or has_vel else [f"{'/'.join(POSE)} or {'/'.join(VEL)}"]
        raise CalibrationError(f"{path}: missing column(s) {missing + odo}; header is {header}")
    cols = list(need) + list(POSE if has_pose else VEL)
    data = np.empty((len(rows), len(cols)))
    for i, row in enumerate(rows):
        row = {k.strip(): v for k, v in row.items() if k is not None}
        for j, c in enumerate(cols):
            try:
                data[i, j] = float(row[c])
            except (TypeError, ValueError):
                raise CalibrationError(f"{path}: row {i + 2}, column {c}: {row.get(c)!r} is not a number") from None
    if len(data) < 20:
        raise CalibrationError(f"{path}: {len(data)} rows; need at least 20")
    if not np.all(np.isfinite(data)):
        i = int(np.flatnonzero(~np.all(np.isfinite(data), axis=1))[0])
        raise CalibrationError(f"{path}: row {i + 2} has a non-finite value")
    t = data[:, 0]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0])
        raise CalibrationError(f"{path}: timestamps not strictly increasing at row {i + 3} "
                               f"(t = {float(t[i + 1])!r} after {float(t[i])!r})")
    dt = np.diff(t)
    if dt.max() > 5 * np.median(dt):
        i = int(np.argmax(dt))
        raise CalibrationError(f"{path}: gap of {dt[i]:.3f} s at row {i + 3} (median step {np.median(dt):.3f} s)")
    cmd = data[:, 1:4]
    vel = body_velocity_from_pose(t, data[:, 4:7]) if has_pose else data[:, 4:7]
    return DynamicsLog(t - t[0], cmd, vel, has_pose, str(path))


def write_log(path: str | Path, t: np.ndarray, cmd: np.ndarray, pose: np.ndarray) -> Path:
    """Write a log in the pose form (atomically)."""
    lines = ["t," + ",".join(CMD + POSE)]
    for ti, c, p in zip(t, cmd, pose, strict=True):
        lines.append(f"{ti:.4f}," + ",".join(f"{v:.6f}" for v in (*c, *p)))
    return write_text(path, "\n".join(lines) + "\n")


def excitation_plan(params: RobotParams, dt: float, seed: int = 0, steps_per_axis: int = 8,
                    hold_s: float = 2.5) -> np.ndarray:
    """Commands (N, 3) exciting one axis at a time: steps of random size (some beyond the limits), each
    followed by a stop, so that latency, lag, acceleration and speed limits all show."""
    rng = np.random.default_rng(seed)
    limits = (params.max_speed, params.max_speed, params.max_yaw_rate)
    hold = int(round(hold_s / dt))
    out = [np.zeros((hold, 3))]
    for axis, lim in enumerate(limits):
        amps = rng.uniform(0.3, 1.6, steps_per_axis) * lim * rng.choice([-1.0, 1.0], steps_per_axis)
        amps[:2] = (1.5 * lim, -0.5 * lim)  # one saturating and one small step for certain
        for a in amps:
            seg = np.zeros((2 * hold, 3))
            seg[:hold, axis] = a
            out.append(seg)
    return np.concatenate(out)


def simulate_log(params: RobotParams, cmd: np.ndarray, dt: float, pose_noise: float = 0.0,
                 yaw_noise: float = 0.0, seed: int = 0, sim_dt: float = 0.005) -> tuple[np.ndarray, np.ndarray]:
    """Run ``HolonomicBase`` on ``cmd`` (one row per ``dt``); returns times and odometry poses (+ noise).

    The base is stepped every ``sim_dt`` (at most; a whole fraction of ``dt``) so that it stands in for a
    continuous robot: the env's coarse control period adds its own discretisation, which is not the robot's.
    """
    sub = max(1, int(round(dt / sim_dt)))
    base = HolonomicBase(params, dt / sub)
    base.reset(np.zeros(3))
    rng = np.random.default_rng(seed)
    poses = np.empty((len(cmd), 3))
    for i, c in enumerate(cmd):
        poses[i] = base.pose
        for _ in range(sub):
            base.step(c)
    poses[:, :2] += rng.normal(0, pose_noise, (len(cmd), 2))
    poses[:, 2] = np.mod(poses[:, 2] + rng.normal(0, yaw_noise, len(cmd)) + math.pi, 2 * math.pi) - math.pi
    return dt * np.arange(len(cmd)), poses
