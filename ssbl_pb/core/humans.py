"""Conversation groups: F-formation spawning and the members' motion under the social forces (eqs. 8-10).

Model (ref "Social force field model", with the departures noted in ``SocialParams``):

* The members stand where their layout puts them (``layouts``: calibrated on real groups, or the paper's
  o-space circle), each at its own distance from the conversation centre ``o``, facing it.
* A robot coming within ``join_radius + join_margin`` of the centre joins progressively (weight ``w`` in
  [0, 1]; ``join_radius`` is the distance of its place from the centre): the ring widens toward
  ``joined_radius``, and in the paper's model the centre moves toward the robot by ``w/(n+1)`` of the way, as
  it would if the robot were one more member. Members then re-form around the centre: they step back and
  apart, which opens a place for the newcomer. Repulsion from the robot (eq. 8) acts whenever it is inside a
  member's personal zone, joined or not.
* Each member moves by ``F = w_c n(F_c) + w_e g n(F_e) + w_r n(F_r)`` (``n`` a soft normalisation, ``g`` the
  ref's equality gate), applied as ``force_newton * n(F)`` to a 1 kg body with linear drag, integrated exactly
  over one control step (speed capped at ``max_speed``).

``group_step`` and ``free_slot`` (compiled) are the only implementation: the training batch (``kernels``), the
env and ``Group`` (one group, for the world, calibration and tests) all run them on the arrays of
``GroupArrays``, whose row ``i`` is one group padded to ``MAX_HUMANS`` members.
* Members face the conversation centre. The paper's orientations ``d_e + d_c`` point at the neighbours'
  centroid, which is the same for symmetric groups but would turn an L-shaped or side-by-side pair toward each
  other and break the formation; ``field_at`` still returns them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..params import SocialParams
from .base import clip, wrap_angle
from .forces import EPS, cohesion_on, equality_on, repulsion_on
from .layouts import Layout, formation_angles, free_layout, paper_layout  # noqa: F401 (formation_angles: re-exported)

MAX_HUMANS = 5
TWO_PI = 2.0 * math.pi
# the SFFM's parameters as the compiled step reads them (``sffm_params``)
(D_P, D_S, D_PUB, W_COH, W_EQ, W_REP, NEWTON_PER_DRAG, DRAG, SATURATION, DEADBAND, MEMBER_MAX_SPEED, TURN_RATE,
 JOIN_MARGIN, DT, N_SFFM) = range(15)
# per-group scalars, columns of ``GroupArrays.scalars``
(BASE_RADIUS, JOINED_RADIUS, JOIN_RADIUS, KEEP, SHIFT, RADIUS, JOIN_WEIGHT, N_SCALARS) = range(8)


def sffm_params(social: SocialParams, dt: float) -> np.ndarray:
    """``SocialParams`` packed for ``group_step`` (indices: this module's constants)."""
    p = np.zeros(N_SFFM)
    for k, v in {D_P: social.personal_radius, D_S: social.social_radius, D_PUB: social.public_radius,
                 W_COH: social.weight_cohesion, W_EQ: social.weight_equality, W_REP: social.weight_repulsion,
                 NEWTON_PER_DRAG: social.force_newton / social.mass / social.drag, DRAG: social.drag,
                 SATURATION: social.saturation, DEADBAND: social.equality_deadband,
                 MEMBER_MAX_SPEED: social.max_speed, TURN_RATE: social.max_turn_rate,
                 JOIN_MARGIN: social.join_margin, DT: dt}.items():
        p[k] = v
    return p


@njit(cache=True)
def _gaps(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angles sorted in [0, 2 pi) and the gap after each (to the next, the last wrapping to the first)."""
    a = np.sort(angles % TWO_PI)
    n = a.shape[0]
    gaps = np.empty(n)
    for j in range(n - 1):
        gaps[j] = a[j + 1] - a[j]
    gaps[n - 1] = a[0] + TWO_PI - a[n - 1]
    return a, gaps


@njit(cache=True)
def widest_gap(angles: np.ndarray, toward: float, use_toward: bool, tie_deg: float) -> tuple[float, float]:
    """Mid-angle and size (rad) of the widest angular gap between members. Gaps within ``tie_deg`` of the widest
    are ties; with ``use_toward`` the tie whose middle is closest to ``toward`` wins (the robot's side of a
    vis-a-vis pair), else the widest of them."""
    a, gaps = _gaps(angles)
    tie = gaps.max() - math.radians(tie_deg)
    pick, pick_err = -1, np.inf
    for j in range(a.shape[0]):
        if gaps[j] < tie:
            continue
        err = abs(wrap_angle(a[j] + gaps[j] / 2.0 - toward)) if use_toward else -gaps[j]
        if err < pick_err:
            pick, pick_err = j, err
    return (a[pick] + gaps[pick] / 2.0) % TWO_PI, gaps[pick]


@njit(cache=True)
def slot_distance(rel: np.ndarray, ux: float, uy: float, radius: float, keep: float) -> float:
    """How far from the centre, along the unit direction (ux, uy), the robot's place is: ``radius`` (the o-space
    ring), or further out until its centre is ``keep`` metres from every member (``rel``: members relative to the
    centre, in index order)."""
    t = radius
    if keep <= 0.0:
        return t
    for _ in range(rel.shape[0]):
        moved = False
        for j in range(rel.shape[0]):
            qx, qy = rel[j, 0], rel[j, 1]
            b = qx * ux + qy * uy
            h2 = qx * qx + qy * qy - b * b
            if (t - b) * (t - b) + h2 < keep * keep:
                t = b + math.sqrt(max(keep * keep - h2, 0.0))
                moved = True
        if not moved:
            break
    return t


@njit(cache=True)
def free_slot(n: int, pos: np.ndarray, cx: float, cy: float, radius: float, keep: float, rx: float, ry: float,
              use_robot: bool) -> tuple[float, float]:
    """The free slot: the middle of the widest gap between the ``n`` members at ``pos`` around the centre
    (cx, cy) (ties broken toward the robot at (rx, ry) when ``use_robot``), on the o-space circle or out along
    the gap's middle until the robot keeps ``keep`` from every member (``slot_distance``)."""
    rel = np.empty((n, 2))
    angles = np.empty(n)
    for j in range(n):
        rel[j, 0], rel[j, 1] = pos[j, 0] - cx, pos[j, 1] - cy
        angles[j] = math.atan2(rel[j, 1], rel[j, 0])
    mid, _ = widest_gap(angles, math.atan2(ry - cy, rx - cx), use_robot, 10.0)
    ux, uy = math.cos(mid), math.sin(mid)
    t = slot_distance(rel, ux, uy, radius, keep)
    return cx + t * ux, cy + t * uy


@njit(cache=True)
def update_centre(sp: np.ndarray, g_n: int, rx: float, ry: float, centre0: np.ndarray, join_radius: float,
                  shift: float, base_radius: float, joined_radius: float) -> tuple[float, float, float, float]:
    """A robot at (rx, ry) joins progressively within ``join_margin`` of its place: the joining weight ``w``, the
    conversation centre (moved toward the robot by ``w shift/(n + 1)`` of the way) and the o-space radius
    (widened toward ``joined_radius``). Returns (w, centre x, centre y, radius)."""
    dx, dy = rx - centre0[0], ry - centre0[1]
    w = clip((join_radius + sp[JOIN_MARGIN] - math.hypot(dx, dy)) / sp[JOIN_MARGIN], 0.0, 1.0)
    k = w * shift / (g_n + 1)
    return w, centre0[0] + k * dx, centre0[1] + k * dy, base_radius + w * (joined_radius - base_radius)


@njit(cache=True)
def group_step(sp: np.ndarray, i: int, rx: float, ry: float, count: np.ndarray, pos: np.ndarray, vel: np.ndarray,
               yaw: np.ndarray, centre0: np.ndarray, centre: np.ndarray, scalars: np.ndarray, ring_offset: np.ndarray,
               comfort: np.ndarray, force: np.ndarray, repulsion: np.ndarray, robot_force: np.ndarray) -> None:
    """One control period of group ``i`` (rows of ``GroupArrays``' arrays, updated in place) with the robot at
    (rx, ry): the SFFM forces (eqs. 8-10) on every agent, the members' motion under them, and the same field at
    the robot (``robot_force``: total then repulsion part) for the rewards."""
    n = count[i]
    k = n + 1
    sc = scalars[i]
    w, cx, cy, R = update_centre(sp, n, rx, ry, centre0[i], sc[JOIN_RADIUS], sc[SHIFT], sc[BASE_RADIUS],
                                 sc[JOINED_RADIUS])
    sc[JOIN_WEIGHT], sc[RADIUS] = w, R
    centre[i, 0], centre[i, 1] = cx, cy
    P = np.empty((k, 2))
    P[:n] = pos[i, :n]
    P[n, 0], P[n, 1] = rx, ry
    zones = np.full((k, k), sp[D_P])  # members keep their comfort distance from each other, d_p from the robot
    for a in range(n):
        for b in range(n):
            zones[a, b] = comfort[i, a]
    everyone = np.ones((k, k), dtype=np.bool_)
    members = everyone.copy()  # equality and cohesion count the robot only once it has joined
    if w < 0.5:
        members[:, n] = False
    decay = math.exp(-sp[DRAG] * sp[DT])
    dt, sat, db = sp[DT], sp[SATURATION], sp[DEADBAND]
    for a in range(k):
        frx, fry = repulsion_on(a, P, zones, everyone)
        fex, fey, _, _ = equality_on(a, P, sp[D_S], members)
        ring = R + ring_offset[i, a] if a < n else R
        fcx, fcy, _, _ = cohesion_on(a, P, cx, cy, ring, sp[D_S], sp[D_PUB], members)
        if a == n:
            robot_force[i, 0], robot_force[i, 1] = fcx + fex + frx, fcy + fey + fry
            robot_force[i, 2], robot_force[i, 3] = frx, fry
            continue
        # the ref's gate: equality acts only off the o-space ring (ramped over one dead band)
        gate = clip((abs(math.hypot(P[a, 0] - cx, P[a, 1] - cy) - ring) - db) / db, 0.0, 1.0)
        force[i, a, 0], force[i, a, 1] = fcx + gate * fex + frx, fcy + gate * fey + fry
        repulsion[i, a, 0], repulsion[i, a, 1] = frx, fry
        # w_c n(F_c) + w_e g n(F_e) + w_r n(F_r), n a soft normalisation
        nc, ne, nr = max(math.hypot(fcx, fcy), sat), max(math.hypot(fex, fey), sat), max(math.hypot(frx, fry), sat)
        tx = sp[W_COH] * (fcx / nc) + (sp[W_EQ] * gate) * (fex / ne) + sp[W_REP] * (frx / nr)
        ty = sp[W_COH] * (fcy / nc) + (sp[W_EQ] * gate) * (fey / ne) + sp[W_REP] * (fry / nr)
        # exact solution of dv/dt = acc - drag v with acc held over dt, speed capped
        st = max(math.hypot(tx, ty), 1.0)
        vix, viy = tx / st * sp[NEWTON_PER_DRAG], ty / st * sp[NEWTON_PER_DRAG]
        v0x, v0y = vel[i, a, 0], vel[i, a, 1]
        vx, vy = vix + (v0x - vix) * decay, viy + (v0y - viy) * decay
        speed = math.hypot(vx, vy)
        if speed > sp[MEMBER_MAX_SPEED]:
            vx, vy = vx * (sp[MEMBER_MAX_SPEED] / speed), vy * (sp[MEMBER_MAX_SPEED] / speed)
        vel[i, a, 0], vel[i, a, 1] = vx, vy
        pos[i, a, 0] = P[a, 0] + (0.5 * dt) * (v0x + vx)
        pos[i, a, 1] = P[a, 1] + (0.5 * dt) * (v0y + vy)
        # turn toward the conversation centre at a bounded rate
        tox, toy = cx - pos[i, a, 0], cy - pos[i, a, 1]
        err = (math.atan2(toy, tox) - yaw[i, a] + math.pi) % TWO_PI - math.pi
        lim = sp[TURN_RATE] * dt
        turn = clip(err, -lim, lim) if math.hypot(tox, toy) > EPS else 0.0
        yaw[i, a] = (yaw[i, a] + turn) % TWO_PI


class GroupArrays:
    """The state of ``num`` groups, each padded to ``MAX_HUMANS`` members (``count`` are real): positions,
    velocities and yaws of the members, the conversation centre at spawn and now, per-member ring offsets and
    comfort distances, the SFFM forces of the last step, and the per-group scalars (``scalars[:, RADIUS]``...)."""

    def __init__(self, num: int) -> None:
        m = MAX_HUMANS
        self.count = np.full(num, 2, dtype=np.int64)
        self.pos, self.vel, self.yaw = np.zeros((num, m, 2)), np.zeros((num, m, 2)), np.zeros((num, m))
        self.centre0, self.centre = np.zeros((num, 2)), np.zeros((num, 2))
        self.scalars = np.zeros((num, N_SCALARS))
        self.ring_offset, self.comfort = np.zeros((num, m)), np.zeros((num, m))
        self.force, self.repulsion = np.zeros((num, m, 2)), np.zeros((num, m, 2))
        self.robot_force = np.zeros((num, 4))  # total field at the robot, then its repulsion part

    def spawn(self, i: int, social: SocialParams, centre: np.ndarray, layout: Layout, keep: float,
              robot_xy: np.ndarray) -> None:
        """Row ``i`` becomes a group at rest in ``layout`` around ``centre`` (see ``Group``), with the robot at
        ``robot_xy`` (its joining weight)."""
        n = len(layout.offsets)
        self.count[i] = n
        for arr in (self.pos, self.vel, self.yaw, self.ring_offset, self.comfort, self.force, self.repulsion):
            arr[i] = 0.0
        self.robot_force[i] = 0.0
        self.centre0[i] = np.asarray(centre, dtype=float)
        self.pos[i, :n] = self.centre0[i] + layout.offsets
        self.yaw[i, :n] = layout.yaw
        base = layout.radius
        self.ring_offset[i, :n] = layout.ring - base  # exactly 0 on the paper's circle
        gaps = np.hypot(*(layout.offsets[:, None] - layout.offsets[None]).transpose(2, 0, 1))
        gaps[np.diag_indices(n)] = np.inf
        self.comfort[i, :n] = np.minimum(social.personal_radius, gaps.min(axis=1))
        sc = self.scalars[i]
        sc[BASE_RADIUS], sc[JOINED_RADIUS] = base, max(base, layout.joined_radius)
        sc[KEEP], sc[SHIFT] = (0.0, 1.0) if layout.paper else (keep, 0.0)
        # the robot counts as joining from the slot's distance at rest (the ring on the paper's circle)
        sx, sy = free_slot(n, self.pos[i], *self.centre0[i], base, sc[KEEP], 0.0, 0.0, False)
        sc[JOIN_RADIUS] = math.hypot(sx - self.centre0[i, 0], sy - self.centre0[i, 1]) if sc[KEEP] > 0 else base
        self.join(i, sffm_params(social, 1.0), robot_xy)

    def join(self, i: int, sp: np.ndarray, robot_xy: np.ndarray) -> None:
        """Row ``i``'s joining weight, centre and radius for a robot at ``robot_xy`` (``update_centre``)."""
        sc = self.scalars[i]
        w, cx, cy, r = update_centre(sp, int(self.count[i]), float(robot_xy[0]), float(robot_xy[1]), self.centre0[i],
                                     sc[JOIN_RADIUS], sc[SHIFT], sc[BASE_RADIUS], sc[JOINED_RADIUS])
        sc[JOIN_WEIGHT], sc[RADIUS] = w, r
        self.centre[i] = cx, cy


def measured_group(social: SocialParams, members: np.ndarray, centre: np.ndarray, keep: float, paper: bool,
                   dt: float = 0.1) -> Group:
    """A group at rest where ``members`` (n, 2) stand around ``centre``, by the env's model (``paper``: the
    original's circle, else the calibrated model with the robot's place ``keep`` from every member): what a
    robot that measures the people (deploy) feeds the policy, with the simulator's own definitions."""
    offsets = np.asarray(members, dtype=float).reshape(-1, 2) - centre
    n = len(offsets)
    if paper:
        angles = np.arctan2(offsets[:, 1], offsets[:, 0])
        lay = paper_layout("circular", n, social, 0.0)
        lay = type(lay)(offsets, np.full(n, lay.radius), np.mod(angles + math.pi, TWO_PI), lay.radius,
                        lay.joined_radius, paper=True)  # the paper's members all belong on the o-space circle
    else:
        lay = free_layout(offsets)
    return Group(social, centre, lay, keep, dt)


class Group:
    """One conversation group: row ``i`` of a ``GroupArrays`` (its own, or a batch's), stepped by ``group_step``.

    ``layout`` (``layouts.Layout``) gives where the members stand at rest: each keeps its own distance from the
    conversation centre (``ring_offset`` from the o-space radius) and, from fellow members, the smaller of the
    personal zone and the distance to its nearest one at spawn (``comfort``), so any layout, real or paper, is
    at rest when left alone. Except on the paper's circle (``layout.paper``): ``keep`` > 0 moves the free slot
    out of the ring until the robot's centre is that far from every member (``slot_distance``), and the
    conversation centre stays put; on the paper's circle the slot stays on the ring and the centre moves toward a
    joining robot by ``w / (n + 1)`` of the way. Attributes are views of the arrays (writes go through).
    """

    def __init__(self, social: SocialParams, centre: np.ndarray | None = None, layout: Layout | None = None,
                 keep: float = 0.0, dt: float = 0.1, arrays: GroupArrays | None = None, i: int = 0) -> None:
        """A new group from ``centre`` and ``layout`` (the robot far away), or a view of row ``i`` of
        ``arrays``."""
        self.social, self.i = social, i
        self._sp = sffm_params(social, dt)
        self.arrays = arrays if arrays is not None else GroupArrays(1)
        if layout is not None:
            self.arrays.spawn(i, social, centre, layout, keep, np.full(2, 1e9))

    n = property(lambda self: int(self.arrays.count[self.i]))
    pos = property(lambda self: self.arrays.pos[self.i, :self.n])
    vel = property(lambda self: self.arrays.vel[self.i, :self.n])
    yaw = property(lambda self: self.arrays.yaw[self.i, :self.n])
    centre0 = property(lambda self: self.arrays.centre0[self.i])
    centre = property(lambda self: self.arrays.centre[self.i])
    ring_offset = property(lambda self: self.arrays.ring_offset[self.i, :self.n])
    comfort = property(lambda self: self.arrays.comfort[self.i, :self.n])
    force = property(lambda self: self.arrays.force[self.i, :self.n])
    repulsion = property(lambda self: self.arrays.repulsion[self.i, :self.n])
    robot_force = property(lambda self: self.arrays.robot_force[self.i, :2])
    robot_repulsion = property(lambda self: self.arrays.robot_force[self.i, 2:])
    base_radius = property(lambda self: float(self.arrays.scalars[self.i, BASE_RADIUS]))
    joined_radius = property(lambda self: float(self.arrays.scalars[self.i, JOINED_RADIUS]))
    join_radius = property(lambda self: float(self.arrays.scalars[self.i, JOIN_RADIUS]))
    keep = property(lambda self: float(self.arrays.scalars[self.i, KEEP]))
    centre_shift = property(lambda self: float(self.arrays.scalars[self.i, SHIFT]))
    radius = property(lambda self: float(self.arrays.scalars[self.i, RADIUS]))
    join_weight = property(lambda self: float(self.arrays.scalars[self.i, JOIN_WEIGHT]))

    def update_centre(self, robot_xy: np.ndarray) -> None:
        """Set ``join_weight``, ``centre`` and ``radius`` for a robot at ``robot_xy``."""
        self.arrays.join(self.i, self._sp, robot_xy)

    def step(self, robot_xy: np.ndarray, dt: float | None = None) -> None:
        """Advance the members by one control period given the robot's position."""
        if dt is not None and dt != self._sp[DT]:
            self._sp = sffm_params(self.social, dt)
        a = self.arrays
        group_step(self._sp, self.i, float(robot_xy[0]), float(robot_xy[1]), a.count, a.pos, a.vel, a.yaw, a.centre0,
                   a.centre, a.scalars, a.ring_offset, a.comfort, a.force, a.repulsion, a.robot_force)

    def member_angles(self) -> np.ndarray:
        """Members' angles around the current conversation centre (rad)."""
        d = self.pos - self.centre
        return np.arctan2(d[:, 1], d[:, 0])

    def free_slot(self, robot_xy: np.ndarray | None = None) -> np.ndarray:
        """The free slot now (``free_slot``; ties toward the robot when ``robot_xy`` is given)."""
        r = (0.0, 0.0) if robot_xy is None else (float(robot_xy[0]), float(robot_xy[1]))
        return np.array(free_slot(self.n, self.pos, *self.centre, self.radius, self.keep, *r, robot_xy is not None))
