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
* Members face the conversation centre. The paper's orientations ``d_e + d_c`` point at the neighbours'
  centroid, which is the same for symmetric groups but would turn an L-shaped or side-by-side pair toward each
  other and break the formation; ``field_at`` still returns them.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import UserError
from ..params import FORMATIONS, SocialParams
from . import forces
from .layouts import Layout


def member_spacing(social: SocialParams, radius: float) -> float:
    """Angle (rad) between neighbours ``min_member_gap`` apart on a circle of ``radius``."""
    return 2.0 * math.asin(min(1.0, social.min_member_gap / (2.0 * radius)))


def formation_angles(formation: str, n: int, social: SocialParams) -> np.ndarray:
    """Members' angles (rad) around the o-space centre, before a random rotation.

    circular: evenly spaced; vis_a_vis: two facing clusters; l_shape: each member 90 deg further along
    (2 members make an L, 3 a U); side_by_side: adjacent members at the closest comfortable spacing.
    """
    if formation not in FORMATIONS:
        raise UserError(f"formation {formation!r}: expected one of {FORMATIONS}")
    if not 2 <= n <= 5:
        raise UserError(f"group size {n}: expected 2 to 5 members")
    radius = social.ospace_radius_for(n)
    delta = member_spacing(social, radius)
    if formation == "circular":
        return 2.0 * math.pi * np.arange(n) / n
    if formation == "side_by_side":
        return delta * np.arange(n)
    if formation == "l_shape":
        return min(max(math.pi / 2, delta), 2.0 * math.pi / n) * np.arange(n)
    a, b = (n + 1) // 2, n // 2  # vis_a_vis
    side_a = (np.arange(a) - (a - 1) / 2.0) * delta
    side_b = math.pi + (np.arange(b) - (b - 1) / 2.0) * delta
    return np.concatenate([side_a, side_b])


def widest_gap(angles: np.ndarray, toward: float | None = None, tie_deg: float = 10.0) -> tuple[float, float]:
    """Mid-angle and size (rad) of the widest angular gap between members.

    Gaps within ``tie_deg`` of the widest are ties; ``toward`` (an angle) picks the tie whose middle is closest
    to it (e.g. the robot's side of a vis-a-vis pair). Plain Python: groups have at most 5 members.
    """
    two_pi = 2.0 * math.pi
    a = sorted(float(x) % two_pi for x in angles)
    gaps = [a[i + 1] - a[i] for i in range(len(a) - 1)] + [a[0] + two_pi - a[-1]]
    best = max(gaps)
    tie = best - math.radians(tie_deg)
    pick, pick_err = -1, math.inf
    for i, g in enumerate(gaps):
        if g < tie:
            continue
        mid = a[i] + g / 2.0
        if toward is None:
            err = -g  # the widest among ties
        else:
            err = abs(math.remainder(mid - toward, two_pi))
        if err < pick_err:
            pick, pick_err = i, err
    return (a[pick] + gaps[pick] / 2.0) % two_pi, gaps[pick]


def combined_force(f_c: np.ndarray, f_e: np.ndarray, f_r: np.ndarray, gate: np.ndarray | float,
                   social: SocialParams) -> np.ndarray:
    """The SFFM's motion force ``w_c n(F_c) + w_e g n(F_e) + w_r n(F_r)`` (ref), ``n`` a soft normalisation."""
    k = len(f_c)
    n = forces.soft_normalize(np.concatenate([f_c, f_e, f_r]), social.saturation)  # one call for all three
    g = np.asarray(gate, dtype=float)
    g = g[..., None] if g.ndim == 1 else g
    return (social.weight_cohesion * n[:k] + (social.weight_equality * g) * n[k:2 * k]
            + social.weight_repulsion * n[2 * k:])


def equality_gate(ring_error: np.ndarray, social: SocialParams) -> np.ndarray:
    """The ref's gate: equality acts only off the o-space ring (ramped over one dead band)."""
    db = social.equality_deadband
    return np.minimum(np.maximum((np.abs(ring_error) - db) / db, 0.0), 1.0)


def slot_distance(rel: np.ndarray, u: np.ndarray, radius: float, keep: float) -> float:
    """How far from the centre, along the unit direction ``u``, the robot's place is: ``radius`` (the o-space
    ring), or further out until its centre is ``keep`` metres from every member (``rel``: members relative to
    the centre). Plain Python, members in index order (``kernels._free_slot`` repeats it)."""
    t = radius
    if keep <= 0.0:
        return t
    for _ in range(len(rel)):
        moved = False
        for qx, qy in rel.tolist():
            b = qx * u[0] + qy * u[1]
            h2 = qx * qx + qy * qy - b * b
            if (t - b) * (t - b) + h2 < keep * keep:
                t = b + math.sqrt(max(keep * keep - h2, 0.0))
                moved = True
        if not moved:
            break
    return t


class Group:
    """State and dynamics of one conversation group of ``n`` members (arrays, metres, radians).

    ``layout`` (``layouts.Layout``) gives where the members stand at rest: each keeps its own distance from the
    conversation centre (``ring_offset`` from the o-space radius) and, from fellow members, the smaller of the
    personal zone and the distance to its nearest one at spawn (``comfort``), so any layout, real or paper, is
    at rest when left alone. Except on the paper's circle (``layout.paper``): ``keep`` > 0 moves the free slot
    out of the ring until the robot's centre is that far from every member (``slot_distance``), and the
    conversation centre stays put (``centre_shift`` 0); on the paper's circle the slot stays on the ring and the
    centre moves toward a joining robot by ``w / (n + 1)`` of the way (``centre_shift`` 1).
    """

    def __init__(self, social: SocialParams, centre: np.ndarray, layout: Layout, keep: float = 0.0) -> None:
        self.social = social
        self.n = n = len(layout.offsets)
        self.base_radius = layout.radius
        self.joined_radius = max(self.base_radius, layout.joined_radius)
        self.ring_offset = layout.ring - self.base_radius  # exactly 0 on the paper's circle
        self.keep, self.centre_shift = (0.0, 1.0) if layout.paper else (keep, 0.0)
        self.centre0 = np.asarray(centre, dtype=float).copy()
        self.pos = self.centre0 + layout.offsets
        self.vel = np.zeros((n, 2))
        self.yaw = layout.yaw.copy()
        self.centre = self.centre0.copy()
        self.radius = self.base_radius
        self.join_weight = 0.0
        self.force = np.zeros((n, 2))  # total SFFM force on each member (pre-normalisation sum)
        self.repulsion = np.zeros((n, 2))  # its repulsion part
        self.robot_force = np.zeros(2)  # the same field evaluated at the robot (used by rewards R1/R2)
        self.robot_repulsion = np.zeros(2)  # its repulsion part (the members' push on the robot; metrics)
        k = n + 1
        self._mask_members = np.ones((k, k), dtype=bool)
        self._mask_members[:, -1] = False  # robot not a participant (repulsion ignores this mask)
        self._mask_joined = np.ones((k, k), dtype=bool)
        gaps = np.hypot(*(layout.offsets[:, None] - layout.offsets[None]).transpose(2, 0, 1))
        gaps[np.diag_indices(n)] = np.inf
        self.comfort = np.minimum(social.personal_radius, gaps.min(axis=1))
        self._zones = np.full((k, k), social.personal_radius)  # repulsion zones; member-member: comfort
        self._zones[:n, :n] = self.comfort[:, None]
        # the robot counts as joining from the slot's distance at rest (the ring on the paper's circle)
        self.join_radius = float(np.hypot(*(self.free_slot() - self.centre0))) if self.keep > 0 else self.base_radius

    # -- the conversation centre as seen with a (possibly) joining robot --------------------------------
    def update_centre(self, robot_xy: np.ndarray) -> None:
        """Set ``join_weight``, ``centre`` and ``radius`` for a robot at ``robot_xy``."""
        s = self.social
        d = math.hypot(robot_xy[0] - self.centre0[0], robot_xy[1] - self.centre0[1])
        w = (self.join_radius + s.join_margin - d) / s.join_margin
        w = min(1.0, max(0.0, w))
        self.join_weight = w
        self.centre = self.centre0 + (w * self.centre_shift / (self.n + 1)) * (robot_xy - self.centre0)
        self.radius = self.base_radius + w * (self.joined_radius - self.base_radius)

    def field_at(self, agents: np.ndarray, joined: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw SFFM forces for all agents (members then robot): cohesion, equality, repulsion, orientation."""
        s = self.social
        mask = self._mask_joined if joined else self._mask_members
        pair = forces.pairwise(agents)
        f_r = forces.repulsion(agents, self._zones, pair=pair)
        f_e, d_e = forces.equality(agents, s.social_radius, mask, pair)
        rings = np.append(self.radius + self.ring_offset, self.radius)
        f_c, d_c = forces.cohesion(agents, self.centre, rings, s.social_radius, s.public_radius, mask, pair)
        return f_c, f_e, f_r, d_e + d_c

    def step(self, robot_xy: np.ndarray, dt: float) -> None:
        """Advance the members by ``dt`` seconds given the robot's position."""
        s = self.social
        self.update_centre(robot_xy)
        agents = np.concatenate([self.pos, robot_xy[None, :2]])
        f_c, f_e, f_r, _ = self.field_at(agents, self.join_weight >= 0.5)
        self.robot_force = f_c[-1] + f_e[-1] + f_r[-1]
        self.robot_repulsion = f_r[-1]
        n = self.n
        f_c, f_e, f_r = f_c[:n], f_e[:n], f_r[:n]
        rel = self.pos - self.centre
        gate = equality_gate(np.hypot(rel[:, 0], rel[:, 1]) - (self.radius + self.ring_offset), s)[:, None]
        total = combined_force(f_c, f_e, f_r, gate, s)
        self.force = f_c + gate * f_e + f_r
        self.repulsion = f_r
        # exact solution of dv/dt = acc - drag v with acc held over dt
        decay = math.exp(-s.drag * dt)
        v_inf = forces.soft_normalize(total, 1.0) * (s.force_newton / s.mass / s.drag)
        v0 = self.vel
        vel = v_inf + (v0 - v_inf) * decay
        speed = np.hypot(vel[:, 0], vel[:, 1])
        if speed.max() > s.max_speed:
            vel *= np.minimum(1.0, s.max_speed / speed)[:, None]
        self.vel = vel
        self.pos = self.pos + (0.5 * dt) * (v0 + vel)
        # turn toward the conversation centre at a bounded rate
        to_o = self.centre - self.pos
        want = np.arctan2(to_o[:, 1], to_o[:, 0])
        err = np.remainder(want - self.yaw + math.pi, 2.0 * math.pi) - math.pi
        lim = s.max_turn_rate * dt
        turn = np.minimum(np.maximum(err, -lim), lim)
        turn[np.hypot(to_o[:, 0], to_o[:, 1]) <= 1e-9] = 0.0
        self.yaw = np.remainder(self.yaw + turn, 2.0 * math.pi)

    def member_angles(self) -> np.ndarray:
        """Members' angles around the current conversation centre (rad)."""
        d = self.pos - self.centre
        return np.arctan2(d[:, 1], d[:, 0])

    def free_slot(self, robot_xy: np.ndarray | None = None) -> np.ndarray:
        """The free slot: the middle of the widest gap between members, on the current o-space circle (or out
        along the gap's middle until the robot keeps ``keep`` from every member)."""
        toward = None
        if robot_xy is not None:
            d = robot_xy - self.centre
            toward = math.atan2(d[1], d[0])
        mid, _ = widest_gap(self.member_angles(), toward)
        u = np.array([math.cos(mid), math.sin(mid)])
        return self.centre + slot_distance(self.pos - self.centre, u, self.radius, self.keep) * u
