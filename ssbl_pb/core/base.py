"""Pepper's holonomic base: velocity commands within the real limits (one compiled step, ``base_step``).

State: pose ``(x, y, yaw)`` and world-frame velocity ``(vx, vy, wz)``. A command is a body-frame velocity
``(forward, left, turn)`` in m/s and rad/s. The command is delayed by ``latency_s`` (fractions of a period
interpolate between commands), passed through a first-order lag ``time_constant_s`` (both identified from logs
by ``ssbl_pb.calib``; zero by default), clipped to the speed limits, and reached at most at the acceleration
limits (``RobotParams``). ``base_step`` is the only implementation: the training batch (``kernels``), the env and
``HolonomicBase`` (a single base for the world, deploy's simulated robot and calibration) all call it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..params import RobotParams

TWO_PI = 2.0 * math.pi


class BaseParams(NamedTuple):
    """``RobotParams`` as the compiled step reads them (a control period ``dt``)."""

    max_speed: float
    max_yaw_rate: float
    max_accel: float
    max_yaw_accel: float
    time_constant: float
    delay_steps: int
    delay_frac: float
    dt: float

    @classmethod
    def of(cls, robot: RobotParams, dt: float) -> BaseParams:
        delay = round(robot.latency_s / dt, 9)
        return cls(robot.max_speed, robot.max_yaw_rate, robot.max_accel, robot.max_yaw_accel, robot.time_constant_s,
                   int(delay), delay - int(delay), dt)


@njit(cache=True)
def wrap_angle(x: float) -> float:
    """``math.remainder(x, 2 pi)``: the angle in [-pi, pi]."""
    return x - TWO_PI * np.rint(x / TWO_PI)


@njit(cache=True)
def clip(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@njit(cache=True)
def base_step(max_speed: float, max_yaw_rate: float, max_accel: float, max_yaw_accel: float, time_constant: float,
              delay_steps: int, delay_frac: float, dt: float, pose: np.ndarray, vel: np.ndarray, queue: np.ndarray,
              fx: float, fy: float, w: float) -> tuple[float, float, float]:
    """One control period of the base (``pose``, ``vel`` (3,) and the latency ``queue`` (L, 3) updated in place)
    under the body-frame command (fx, fy, w); returns the command after the speed limits."""
    n = math.hypot(fx, fy)
    if n > max_speed:
        fx, fy = fx * max_speed / n, fy * max_speed / n
    w = clip(w, -max_yaw_rate, max_yaw_rate)
    accepted = (fx, fy, w)
    k, f = delay_steps, delay_frac
    if k > 0 or f != 0.0:  # [0] is now; a fractional latency blends two past commands
        for j in range(queue.shape[0] - 1, 0, -1):
            queue[j] = queue[j - 1]
        queue[0, 0], queue[0, 1], queue[0, 2] = fx, fy, w
        if f == 0.0:
            fx, fy, w = queue[k, 0], queue[k, 1], queue[k, 2]
        else:
            fx = (1.0 - f) * queue[k, 0] + f * queue[k + 1, 0]
            fy = (1.0 - f) * queue[k, 1] + f * queue[k + 1, 1]
            w = (1.0 - f) * queue[k, 2] + f * queue[k + 1, 2]
    x, y, yaw = pose[0], pose[1], pose[2]
    vx, vy, wz = vel[0], vel[1], vel[2]
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty, tw = c * fx - s * fy, s * fx + c * fy, w  # target velocity, world frame
    if time_constant > 0:  # first-order lag toward it
        g = 1.0 - math.exp(-dt / time_constant)
        tx, ty, tw = vx + (tx - vx) * g, vy + (ty - vy) * g, wz + (tw - wz) * g
    dvx, dvy = tx - vx, ty - vy  # reached at most at the acceleration limits
    n = math.hypot(dvx, dvy)
    amax = max_accel * dt
    if n > amax:
        dvx, dvy = dvx * amax / n, dvy * amax / n
    wmax = max_yaw_accel * dt
    dw = clip(tw - wz, -wmax, wmax)
    nvx, nvy, nwz = vx + dvx, vy + dvy, wz + dw
    pose[0] = x + 0.5 * (vx + nvx) * dt  # trapezoidal integration
    pose[1] = y + 0.5 * (vy + nvy) * dt
    pose[2] = wrap_angle(yaw + 0.5 * (wz + nwz) * dt)
    vel[0], vel[1], vel[2] = nvx, nvy, nwz
    return accepted


@njit(cache=True)
def footprint_distance(dx: float, dy: float, yaw: float, half_length: float, half_width: float
                       ) -> tuple[float, float, float]:
    """Distance (m) from the footprint (a box with these half extents, turned by ``yaw``) to a point at (dx, dy)
    from its centre (0 inside), and the unit direction (frame of dx, dy) from the footprint's nearest point to the
    point (straight out from the middle for a point inside)."""
    c, s = math.cos(yaw), math.sin(yaw)
    lx, ly = dx * c + dy * s, -dx * s + dy * c  # -> body frame
    ox, oy = lx - clip(lx, -half_length, half_length), ly - clip(ly, -half_width, half_width)
    dist = math.hypot(ox, oy)
    if dist < 1e-9:
        ox, oy = lx, ly
    norm = max(math.hypot(ox, oy), 1e-9)
    ux, uy = ox / norm, oy / norm
    return dist, ux * c - uy * s, ux * s + uy * c


@njit(cache=True)
def wall_clearance(x: float, y: float, yaw: float, half_length: float, half_width: float, room_x: float,
                   room_y: float) -> tuple[float, float, float, float]:
    """Distance (m) from the footprint's nearest corner to each wall's inner face (+x, -x, +y, -y) of a room of
    ``room_x`` x ``room_y`` metres centred on the origin."""
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    ex, ey = half_length * c + half_width * s, half_length * s + half_width * c  # half-extent along x and y
    return room_x / 2 - x - ex, x - ex + room_x / 2, room_y / 2 - y - ey, y - ey + room_y / 2


def limit_command(cmd: np.ndarray, p: RobotParams) -> np.ndarray:
    """Clip a body-frame command (forward, left, turn) to the speed limits (planar speed as a vector norm)."""
    fx, fy, w = float(cmd[0]), float(cmd[1]), float(cmd[2])
    n = math.hypot(fx, fy)
    if n > p.max_speed:
        fx, fy = fx * p.max_speed / n, fy * p.max_speed / n
    return np.array([fx, fy, min(max(w, -p.max_yaw_rate), p.max_yaw_rate)])


class HolonomicBase:
    """One base stepped by ``base_step``; ``pose``, ``vel`` and the latency queue are rows ``i`` of arrays that
    may be shared with a batch (``BaseArrays``), so the env's world shows the batch's state without copying."""

    def __init__(self, params: RobotParams, dt: float, arrays: BaseArrays | None = None, i: int = 0) -> None:
        self.p, self.dt = params, dt
        self.bp = BaseParams.of(params, dt)
        self.arrays = arrays if arrays is not None else BaseArrays(1, self.bp)
        self.i = i

    @property
    def pose(self) -> np.ndarray:
        return self.arrays.pose[self.i]

    @pose.setter
    def pose(self, value: np.ndarray) -> None:
        self.arrays.pose[self.i] = value

    @property
    def vel(self) -> np.ndarray:
        """World-frame (vx, vy, wz)."""
        return self.arrays.vel[self.i]

    @vel.setter
    def vel(self, value: np.ndarray) -> None:
        self.arrays.vel[self.i] = value

    def reset(self, pose: np.ndarray) -> None:
        """Place the base at rest at ``pose`` (x, y, yaw)."""
        self.arrays.reset(self.i, pose)

    def step(self, cmd: np.ndarray) -> np.ndarray:
        """Apply a body-frame command for one period; returns the limited command actually accepted."""
        a = self.arrays
        return np.array(base_step(*self.bp, a.pose[self.i], a.vel[self.i], a.queue[self.i], float(cmd[0]),
                                  float(cmd[1]), float(cmd[2])))

    @property
    def body_velocity(self) -> np.ndarray:
        """(forward, left, turn) velocity in the body frame."""
        (vx, vy, wz), c, s = self.vel, math.cos(self.pose[2]), math.sin(self.pose[2])
        return np.array([c * vx + s * vy, -s * vx + c * vy, wz])


class BaseArrays:
    """The state of ``num`` bases: ``pose`` and ``vel`` (num, 3), the latency ``queue`` (num, L, 3)."""

    def __init__(self, num: int, bp: BaseParams) -> None:
        self.pose, self.vel = np.zeros((num, 3)), np.zeros((num, 3))
        self.queue = np.zeros((num, bp.delay_steps + 2, 3))  # the latency's commands, [0] is now

    def reset(self, i: int, pose: np.ndarray) -> None:
        self.pose[i] = np.asarray(pose, dtype=float)[:3]
        self.vel[i] = 0.0
        self.queue[i] = 0.0
