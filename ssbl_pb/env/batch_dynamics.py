"""The base's and the members' motion for many independent episodes at once (array form of ``base`` and ``humans``).

Each function mirrors its single-episode original line for line, over a leading batch axis ``N``; groups are
padded to ``MAX_HUMANS`` members with a ``present`` mask (padding sits far away and never feels or exerts a force).
``tests/test_batched.py`` checks every step against the single-episode classes; change both together.
"""

from __future__ import annotations

import math

import numpy as np

from ..params import RobotParams, SocialParams
from . import forces
from .angles import TWO_PI, wrap
from .humans import combined_force, equality_gate

PAD_XY = 1.0e4  # where padding members stand (m): beyond every SFFM zone of every real agent


def limit_commands(cmd: np.ndarray, p: RobotParams) -> np.ndarray:
    """``base.limit_command`` for commands (N, 3)."""
    out = np.array(cmd, dtype=float)
    n = np.hypot(out[:, 0], out[:, 1])
    over = n > p.max_speed
    if over.any():
        out[over, :2] = out[over, :2] * p.max_speed / n[over, None]
    np.clip(out[:, 2], -p.max_yaw_rate, p.max_yaw_rate, out=out[:, 2])
    return out


class BaseBatch:
    """``base.HolonomicBase`` for N bases: ``pose`` (N, 3) and world-frame ``vel`` (N, 3)."""

    def __init__(self, params: RobotParams, dt: float, n: int) -> None:
        self.p, self.dt = params, dt
        delay = round(params.latency_s / dt, 9)
        self._delay_steps, self._delay_frac = int(delay), delay - int(delay)
        self.pose = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        self._queue = np.zeros((n, self._delay_steps + 2, 3))  # [:, 0] is now, as HolonomicBase's deque

    def reset(self, i: int, pose: np.ndarray) -> None:
        """Place base ``i`` at rest at ``pose`` with an empty command history."""
        self.pose[i] = pose
        self.vel[i] = 0.0
        self._queue[i] = 0.0

    def step(self, cmd: np.ndarray) -> None:
        """Apply body-frame commands (N, 3) for one period (``HolonomicBase.step``)."""
        p, dt = self.p, self.dt
        accepted = limit_commands(cmd, p)
        k, f = self._delay_steps, self._delay_frac
        if k == 0 and f == 0.0:
            fx, fy, w = accepted[:, 0], accepted[:, 1], accepted[:, 2]
        else:
            self._queue[:, 1:] = self._queue[:, :-1].copy()
            self._queue[:, 0] = accepted
            q = self._queue
            fx, fy, w = (q[:, k] if f == 0.0 else (1.0 - f) * q[:, k] + f * q[:, k + 1]).T
        yaw = self.pose[:, 2]
        vx, vy, wz = self.vel[:, 0], self.vel[:, 1], self.vel[:, 2]
        c, s = np.cos(yaw), np.sin(yaw)
        tx, ty, tw = c * fx - s * fy, s * fx + c * fy, w
        if p.time_constant_s > 0:
            kk = 1.0 - math.exp(-dt / p.time_constant_s)
            tx, ty, tw = vx + (tx - vx) * kk, vy + (ty - vy) * kk, wz + (tw - wz) * kk
        dvx, dvy = tx - vx, ty - vy
        n = np.hypot(dvx, dvy)
        amax = p.max_accel * dt
        over = n > amax
        if over.any():
            dvx[over], dvy[over] = dvx[over] * amax / n[over], dvy[over] * amax / n[over]
        wmax = p.max_yaw_accel * dt
        dw = np.minimum(np.maximum(tw - wz, -wmax), wmax)
        vel = np.empty_like(self.vel)  # new arrays: callers keep the previous ones as "before" states
        vel[:, 0], vel[:, 1], vel[:, 2] = vx + dvx, vy + dvy, wz + dw
        pose = np.empty_like(self.pose)
        pose[:, :2] = self.pose[:, :2] + 0.5 * (self.vel[:, :2] + vel[:, :2]) * dt
        pose[:, 2] = wrap(yaw + 0.5 * (wz + vel[:, 2]) * dt)
        self.pose, self.vel = pose, vel


class GroupBatch:
    """``humans.Group`` for N groups padded to ``m`` members (arrays lead with N; ``present`` (N, m))."""

    def __init__(self, social: SocialParams, n: int, m: int) -> None:
        self.social, self.m = social, m
        self.count = np.zeros(n, dtype=int)
        self.present = np.zeros((n, m), dtype=bool)
        self.base_radius = np.ones(n)
        self.joined_radius = np.ones(n)
        self.centre0 = np.zeros((n, 2))
        self.pos = np.full((n, m, 2), PAD_XY)
        self.vel = np.zeros((n, m, 2))
        self.yaw = np.zeros((n, m))
        self.centre = np.zeros((n, 2))
        self.radius = np.ones(n)
        self.join_weight = np.zeros(n)
        self.force = np.zeros((n, m, 2))
        self.repulsion = np.zeros((n, m, 2))
        self.robot_force = np.zeros((n, 2))
        # neighbour masks over the agents (members, then the robot last): the robot is a participant only
        # once it has joined; padding never is (repulsion uses ``_agents`` alone, as Group passes no mask)
        self._agents = np.zeros((n, 1, m + 1), dtype=bool)
        self._agents[:, :, m] = True

    def set(self, i: int, group: object) -> None:
        """Copy a freshly spawned ``humans.Group`` into slot ``i`` (resets are rare and reuse its spawning)."""
        k = group.n  # type: ignore[attr-defined]
        self.count[i] = k
        self.present[i] = np.arange(self.m) < k
        self._agents[i, 0, :self.m] = self.present[i]
        for name in ("base_radius", "joined_radius", "join_weight", "radius"):
            getattr(self, name)[i] = getattr(group, name)
        for name in ("centre0", "centre", "robot_force"):
            getattr(self, name)[i] = getattr(group, name)
        for name, pad in (("pos", PAD_XY), ("vel", 0.0), ("yaw", 0.0), ("force", 0.0), ("repulsion", 0.0)):
            arr = getattr(self, name)
            arr[i] = pad
            arr[i, :k] = getattr(group, name)

    def update_centre(self, robot_xy: np.ndarray) -> None:
        """``Group.update_centre`` for robots at ``robot_xy`` (N, 2)."""
        s = self.social
        rel = robot_xy - self.centre0
        d = np.hypot(rel[:, 0], rel[:, 1])
        w = np.minimum(1.0, np.maximum(0.0, (self.base_radius + s.join_margin - d) / s.join_margin))
        self.join_weight = w
        self.centre = self.centre0 + (w / (self.count + 1))[:, None] * rel
        self.radius = self.base_radius + w * (self.joined_radius - self.base_radius)

    def step(self, robot_xy: np.ndarray, dt: float) -> None:
        """``Group.step`` for all groups."""
        s, m = self.social, self.m
        self.update_centre(robot_xy)
        agents = np.concatenate([self.pos, robot_xy[:, None, :]], axis=1)
        participants = self._agents.copy()
        participants[:, 0, m] = self.join_weight >= 0.5
        pair = forces.pairwise(agents)
        f_r = forces.repulsion(agents, s.personal_radius, self._agents, pair)
        f_e, _ = forces.equality(agents, s.social_radius, participants, pair)
        f_c, _ = forces.cohesion(agents, self.centre[:, None, :], self.radius[:, None], s.social_radius,
                                 s.public_radius, participants, pair)
        self.robot_force = f_c[:, m] + f_e[:, m] + f_r[:, m]
        f_c, f_e, f_r = f_c[:, :m], f_e[:, :m], f_r[:, :m]
        rel = self.pos - self.centre[:, None, :]
        gate = equality_gate(np.hypot(rel[..., 0], rel[..., 1]) - self.radius[:, None], s)[..., None]
        total = combined_force(f_c, f_e, f_r, gate, s)
        self.force = f_c + gate * f_e + f_r
        self.repulsion = f_r
        decay = math.exp(-s.drag * dt)
        v_inf = forces.soft_normalize(total, 1.0) * (s.force_newton / s.mass / s.drag)
        v0 = self.vel
        vel = v_inf + (v0 - v_inf) * decay
        speed = np.hypot(vel[..., 0], vel[..., 1])
        if speed.max() > s.max_speed:
            vel = vel * np.minimum(1.0, s.max_speed / np.maximum(speed, 1e-300))[..., None]
        self.vel = vel * self.present[..., None]
        self.pos = self.pos + (0.5 * dt) * (v0 + self.vel)
        to_o = self.centre[:, None, :] - self.pos
        want = np.arctan2(to_o[..., 1], to_o[..., 0])
        err = np.remainder(want - self.yaw + math.pi, TWO_PI) - math.pi
        lim = s.max_turn_rate * dt
        turn = np.minimum(np.maximum(err, -lim), lim)
        turn[np.hypot(to_o[..., 0], to_o[..., 1]) <= 1e-9] = 0.0
        self.yaw = np.remainder(self.yaw + turn, TWO_PI)

    def free_slot(self, robot_xy: np.ndarray, tie_deg: float = 10.0) -> np.ndarray:
        """``Group.free_slot(robot_xy)`` (``humans.widest_gap`` with the robot's side breaking ties), (N, 2)."""
        d = robot_xy - self.centre
        toward = np.arctan2(d[:, 1], d[:, 0])
        dm = self.pos - self.centre[:, None, :]
        a = np.where(self.present, np.mod(np.arctan2(dm[..., 1], dm[..., 0]), TWO_PI), np.inf)
        a = np.sort(a, axis=1)  # present members first (``present`` is a prefix), padding (inf) last
        a0 = np.where(self.present, a, 0.0)
        rows = np.arange(len(a))
        nxt = np.concatenate([a0[:, 1:], a0[:, :1]], axis=1)
        nxt[rows, self.count - 1] = a[:, 0] + TWO_PI  # the gap that wraps around
        gaps = np.where(self.present, nxt - a0, 0.0)
        tie = gaps.max(axis=1) - math.radians(tie_deg)
        mid = a0 + gaps / 2.0
        cand = self.present & (gaps >= tie[:, None])
        err = np.where(cand, np.abs(wrap(mid - toward[:, None])), np.inf)
        pick = np.argmin(err, axis=1)
        best = np.mod(mid[rows, pick], TWO_PI)
        slot = np.empty_like(self.centre)
        slot[:, 0], slot[:, 1] = np.cos(best), np.sin(best)
        return self.centre + self.radius[:, None] * slot
