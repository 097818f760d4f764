"""Pepper's holonomic base: velocity commands within the real limits, as a pure function of arrays.

State: pose ``(x, y, yaw)`` and world-frame velocity ``(vx, vy, wz)``. A command is a body-frame velocity
``(forward, left, turn)`` in m/s and rad/s. The command is delayed by ``latency_s`` (fractions of a period
interpolate between commands), passed through a first-order lag ``time_constant_s`` (both identified from logs
by ``ssbl_pb.calib``; zero by default), clipped to the speed limits, and reached at most at the acceleration
limits (``RobotParams``).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from ..params import RobotParams


def body_to_world(vec: np.ndarray, yaw: float) -> np.ndarray:
    """Rotate a body-frame 2-vector into the world frame."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1]])


def world_to_body(vec: np.ndarray, yaw: float) -> np.ndarray:
    """Rotate a world-frame 2-vector into the body frame."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * vec[0] + s * vec[1], -s * vec[0] + c * vec[1]])


def limit_command(cmd: np.ndarray, p: RobotParams) -> np.ndarray:
    """Clip a body-frame command (forward, left, turn) to the speed limits (planar speed as a vector norm)."""
    fx, fy, w = float(cmd[0]), float(cmd[1]), float(cmd[2])
    n = math.hypot(fx, fy)
    if n > p.max_speed:
        fx, fy = fx * p.max_speed / n, fy * p.max_speed / n
    return np.array([fx, fy, min(max(w, -p.max_yaw_rate), p.max_yaw_rate)])


class HolonomicBase:
    """Integrates Pepper's base for one control period at a time."""

    def __init__(self, params: RobotParams, dt: float) -> None:
        self.p = params
        self.dt = dt
        self.pose = np.zeros(3)
        self.vel = np.zeros(3)  # world frame vx, vy and wz
        self._queue: deque[np.ndarray] = deque()
        self.reset(np.zeros(3))

    def reset(self, pose: np.ndarray) -> None:
        """Place the base at rest at ``pose`` (x, y, yaw)."""
        self.pose = np.asarray(pose, dtype=float).copy()
        self.vel = np.zeros(3)
        delay = round(self.p.latency_s / self.dt, 9)
        self._delay_steps, self._delay_frac = int(delay), delay - int(delay)
        self._queue = deque([np.zeros(3)] * (self._delay_steps + 2), maxlen=self._delay_steps + 2)

    def step(self, cmd: np.ndarray) -> np.ndarray:
        """Apply a body-frame command for one period; returns the limited command actually accepted."""
        p, dt = self.p, self.dt
        accepted = limit_command(cmd, p)
        self._queue.appendleft(accepted)  # [0] is now; a fractional latency blends two past commands
        k, f = self._delay_steps, self._delay_frac
        fx, fy, w = self._queue[k] if f == 0.0 else (1.0 - f) * self._queue[k] + f * self._queue[k + 1]
        x, y, yaw = self.pose
        vx, vy, wz = self.vel
        c, s = math.cos(yaw), math.sin(yaw)
        tx, ty, tw = c * fx - s * fy, s * fx + c * fy, w
        if p.time_constant_s > 0:
            k = 1.0 - math.exp(-dt / p.time_constant_s)
            tx, ty, tw = vx + (tx - vx) * k, vy + (ty - vy) * k, wz + (tw - wz) * k
        dvx, dvy = tx - vx, ty - vy
        n = math.hypot(dvx, dvy)
        amax = p.max_accel * dt
        if n > amax:
            dvx, dvy = dvx * amax / n, dvy * amax / n
        wmax = p.max_yaw_accel * dt
        dw = min(max(tw - wz, -wmax), wmax)
        nvx, nvy, nwz = vx + dvx, vy + dvy, wz + dw
        self.pose = np.array([x + 0.5 * (vx + nvx) * dt, y + 0.5 * (vy + nvy) * dt,
                              math.remainder(yaw + 0.5 * (wz + nwz) * dt, 2.0 * math.pi)])
        self.vel = np.array([nvx, nvy, nwz])
        return accepted

    @property
    def body_velocity(self) -> np.ndarray:
        """(forward, left, turn) velocity in the body frame."""
        return np.concatenate([world_to_body(self.vel[:2], self.pose[2]), self.vel[2:3]])
