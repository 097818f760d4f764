"""Reward terms R1..R5 and effort (paper eqs. 11-15) as pure (compiled) functions of one step's states.

Per step of ``dt`` seconds, with the robot moving by ``du`` through the field ``F`` evaluated at its position at
the start of the step and member j moving by ``du_j`` under its own total force ``F_j``:

* R1 (eq. 11, group forming): ``F . du`` (the line-integral increment).
* R2 (eq. 12, non-increasing energy): ``dt`` if the robot moves along the field (``v . F > 0``, the original
  code's test) else 0.
* R3 (eq. 13, time): ``-dt``; a step that ends the episode by a violation also pays the time it cut short
  (``remaining``), so that crashing early never costs less than waiting for the time-out (ours).
* R4 (success bonus): 1 on the step that completes the approach.
* R5 (eq. 14, altruism): ``-sum_j F_j . du_j`` plus the original's repulsion term ``-sum_j |F_rep,j| dt``
  weighted by ``w_rep`` (how much the robot pushes the members).
* proximity (ours): ``-sum_j max(0, c_j - c'_j) ramp(c'_j)``, the metres by which the robot closes the clearance
  ``c`` to member j while within ``band`` of the intimate zone, weighted by ``ramp`` (0 at ``intimate + band``,
  1 at ``intimate``). Standing still costs nothing, driving at a member does (see ``proximity_cost``).
* displacement (ours): ``-sum_j |du_j|``, the members' path length this step (m), whatever moved them: the
  ``human_displacement_m`` metric (SocNavBench) as a cost. R5 prices the members' work against their own forces
  and its repulsion part ``|F_rep|`` (quadratic in the intrusion), which a robot standing a few cm inside a
  member's personal zone barely pays while the member keeps stepping away (measured).
* arrival (ours): ``-|v|`` (m/s) on the step that completes the approach, the ``arrival_speed`` metric as a cost:
  the success rule only asks for less than ``stop_speed``, so a robot braking at its limit arrives at 0.07-0.1
  m/s whatever the shaping's braking term did before (the paper's hypothesis: slow down into the group).
* effort: ``-|v|^2 dt``, and smoothness ``-|j| dt`` with ``j = (a_t - a_{t-1}) / dt`` the base's jerk (ours,
  see below; L1 so that small jerks still cost).

Total (eq. 15): ``w_e (w1 R1 + w2 R2 + w3 R3) + w4 R4 + w_a (w5 R5 + w_rep R5_rep) + w_effort E + w_smooth S
+ w_slot P + w_prox C + w_disp D + w_arrive A - penalty``. The success bonus stands outside ``w_e`` as in the
original code, which adds +1 on success on top of the weighted per-step reward (eq. 15 writes it inside; with
``w_e = 0.0035`` it would be negligible). ``P`` is the change of ``slot_potential`` (progress toward the free slot
and braking near it; ours) and ``penalty`` applies on a collision or an intrusion into a member's intimate zone.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..params import _check, _nonneg
from .base import wrap_angle

TERMS = ("r1_group_forming", "r2_non_increasing", "r3_time", "r4_success", "r5_altruism", "r5_repulsion",
         "effort", "smoothness", "slot_progress", "proximity", "violation", "displacement", "arrival")
R1, R2, R3, R4, R5, R5_REP, EFFORT, SMOOTH, SLOT, PROX, VIOLATION, DISP, ARRIVAL = range(len(TERMS))
N_TERMS = len(TERMS)


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """Weights of eq. 15 and our additions; ``reference()`` gives the original code's values.

    The original (PepperAgent.CalculateReward, shared/reference/peppersocial.md) uses per-step values
    ``w_e = 0.0035, w_a = 0.9965``, ego ``0.012 v.F + 3.6 [v.F > 0] - 0.16 |v|^2 - 2.0``, alt
    ``-0.012 F_i.v_i - |F_rep,i|/3.8`` and +1 on success. Written per second of our 0.1 s step (our terms
    carry ``dt``) that is ``w1 = 0.12, w2 = 36, w3 = 20, w5 = 0.12, w_rep = 2.63`` and an effort weight of
    ``0.0035 * 1.6`` (effort is part of ego in the original).
    With those, moving along the field earns more per step (+3.6) than time costs (-2.0), so wandering for
    300 steps (+1.7) pays better than arriving (+1): fine for the original's "reach 1 m of the centre" rule,
    not for joining at the free slot. Our defaults keep every term and its sign but make time cost more than
    moving along the field earns, make success worth more than any shaping, add progress toward the free slot
    (potential-based, so it does not change the optimum) and a smoothness cost (the paper's hypothesis is a
    robot that accelerates and decelerates gently), charge closing in on a member near its intimate zone, and
    penalise collisions and intimate-zone intrusions.
    """

    w1: float = 0.05  # R1 group forming
    w2: float = 0.1  # R2 moving along the field (per second)
    w3: float = 0.3  # R3 time (per second)
    w4: float = 2.0  # R4 success bonus
    w5: float = 0.5  # R5 altruism (members' line integrals)
    w_rep: float = 1.0  # R5's repulsion part (per second of |F_rep|)
    w_e: float = 1.0  # egoism weight
    w_a: float = 1.0  # altruism weight
    w_effort: float = 0.1  # -|v|^2 dt
    w_smooth: float = 0.6  # -|jerk| dt, jerk in m/s^3 (training ramps it up from 0.05: configs/)
    w_slot: float = 1.0  # change of slot_potential (per metre of progress toward the free slot)
    w_prox: float = 3.0  # closing in on a member near its intimate zone (per metre closed at the zone's edge)
    violation_penalty: float = 1.0  # collision or intimate-zone intrusion (ends the episode)
    w_disp: float = 0.0  # members' displacement (per metre they moved; 0: off, as the shipped policy trained)
    w_arrive: float = 0.0  # speed on arrival (per m/s on the success step; 0: off, as the shipped policy trained)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            _check(isinstance(v, int | float), "reward", f.name, v, "a number")
        _nonneg("reward", self, *[f.name for f in dataclasses.fields(self)])

    @classmethod
    def reference(cls, dt: float = 0.1) -> RewardWeights:
        """The original Unity code's weights, rescaled to per-second terms at control period ``dt``."""
        return cls(w1=0.012 / dt, w2=3.6 / dt, w3=2.0 / dt, w4=1.0, w5=0.012 / dt, w_rep=1 / 3.8 / dt,
                   w_e=0.0035, w_a=0.9965, w_effort=0.0035 * 0.16 / dt, w_smooth=0.0, w_slot=0.0, w_prox=0.0,
                   violation_penalty=0.0)


@njit(cache=True)
def route_length(x: float, y: float, sx: float, sy: float, cx: float, cy: float, keep_out: float) -> float:
    """Length of the shortest way from (x, y) to the free slot (sx, sy) that enters the group only through it.

    The group is a disc of radius ``keep_out`` around its centre (cx, cy); the way goes around it (tangent, then
    arc) to the point of its rim on the slot's ray, then straight in. Inside the disc it is the straight distance
    plus the arc to the slot's ray, so cutting into the group elsewhere never shortens the way (ours: it makes
    the shaping lead around a group instead of through its members).
    """
    rx, ry, qx, qy = x - cx, y - cy, sx - cx, sy - cy
    r, rq = math.hypot(rx, ry), math.hypot(qx, qy)
    dth = abs(wrap_angle(math.atan2(ry, rx) - math.atan2(qy, qx)))
    R = max(keep_out, rq)
    if r < R:
        return math.hypot(rx - qx, ry - qy) + R * dth
    beta = math.acos(R / r)
    if dth <= beta:  # the rim point on the slot's ray is in plain sight
        to_rim = math.sqrt(max(r * r + R * R - 2.0 * r * R * math.cos(dth), 0.0))
    else:
        to_rim = math.sqrt(r * r - R * R) + R * (dth - beta)
    return to_rim + (R - rq)


def route_distance(p: np.ndarray, slot: np.ndarray, centre: np.ndarray, keep_out: float) -> float:
    """``route_length`` for points given as arrays."""
    return route_length(float(p[0]), float(p[1]), float(slot[0]), float(slot[1]), float(centre[0]),
                        float(centre[1]), float(keep_out))


BRAKE_GAIN = 5.0  # s: slot_potential's weight on speed near the slot
BRAKE_RADIUS = 1.0  # m: within this distance of the slot


@njit(cache=True)
def slot_potential(distance: float, speed: float) -> float:
    """Potential of the robot's state for shaping (ours): minus the distance to the free slot, and minus its
    speed (times ``BRAKE_GAIN`` seconds) within ``BRAKE_RADIUS`` of the slot, so arriving slowly pays. Its
    difference between steps is potential-based shaping (Ng et al. 1999): it does not change the optimum."""
    return -(distance + BRAKE_GAIN * speed * max(0.0, 1.0 - distance / BRAKE_RADIUS))


@njit(cache=True)
def proximity_cost(clearance_before: np.ndarray, clearance_after: np.ndarray, intimate: float,
                   band: float) -> float:
    """Metres the robot closed on members near their intimate zone this step, each weighted by how deep it is in
    the ``band`` beyond the zone (linear: 0 at ``intimate + band``, 1 at ``intimate``); >= 0.

    Ours. The violation penalty alone is a cliff: a policy that circles a group along the intimate zone's edge
    learns nothing until it falls over it. This cost is graded and charges only closing in, so standing at a
    slot between two near neighbours costs (almost) nothing, while grazing a member at full speed does. Closing
    counts whoever moves; members settling around a still robot close at most a few cm per second.
    """
    cost = 0.0
    for j in range(clearance_after.shape[0]):
        closed = max(clearance_before[j] - clearance_after[j], 0.0)
        cost += closed * min(max((intimate + band - clearance_after[j]) * (1.0 / band), 0.0), 1.0)
    return cost


@njit(cache=True)
def step_terms(robot_force: np.ndarray, robot_du: np.ndarray, member_forces: np.ndarray, member_du: np.ndarray,
               member_repulsion: np.ndarray, dt: float, accel: np.ndarray, prev_accel: np.ndarray,
               potential_before: float, potential_after: float, success: bool, violation: bool,
               proximity: float, remaining: float, speed: float) -> np.ndarray:
    """The unweighted terms of one step in ``TERMS`` order (the module docstring gives each formula and unit);
    ``remaining`` is the episode's time left (s) after this step, charged to R3 when it ends in a violation;
    ``speed`` the robot's at the step's end (m/s), charged when it succeeds."""
    dx, dy = robot_du[0], robot_du[1]
    along = robot_force[0] * dx + robot_force[1] * dy  # F . du, and v . F has the same sign
    alt, rep, moved = 0.0, 0.0, 0.0
    for j in range(member_forces.shape[0]):
        alt += member_forces[j, 0] * member_du[j, 0] + member_forces[j, 1] * member_du[j, 1]
        rep += math.hypot(member_repulsion[j, 0], member_repulsion[j, 1])
        moved += math.hypot(member_du[j, 0], member_du[j, 1])
    t = np.empty(N_TERMS)
    t[R1], t[R2], t[R3] = along, dt if along > 0.0 else 0.0, -(dt + remaining) if violation else -dt
    t[R4] = 1.0 if success else 0.0
    t[R5], t[R5_REP] = -alt, -rep * dt
    t[EFFORT] = -(dx * dx + dy * dy) / dt
    t[SMOOTH] = -math.hypot(accel[0] - prev_accel[0], accel[1] - prev_accel[1])
    t[SLOT], t[PROX], t[VIOLATION] = potential_after - potential_before, -proximity, -1.0 if violation else 0.0
    t[DISP] = -moved
    t[ARRIVAL] = -speed if success else 0.0
    return t


def reward_terms(robot_force: np.ndarray, robot_du: np.ndarray, member_forces: np.ndarray, member_du: np.ndarray,
                 member_repulsion: np.ndarray, dt: float, accel: np.ndarray, prev_accel: np.ndarray,
                 potential_before: float, potential_after: float, success: bool, violation: bool,
                 proximity: float = 0.0, remaining: float = 0.0, speed: float = 0.0) -> dict[str, float]:
    """``step_terms`` by name."""
    f = [np.asarray(v, dtype=float).reshape(-1, 2) for v in (member_forces, member_du, member_repulsion)]
    t = step_terms(np.asarray(robot_force, dtype=float), np.asarray(robot_du, dtype=float), *f, float(dt),
                   np.asarray(accel, dtype=float), np.asarray(prev_accel, dtype=float), float(potential_before),
                   float(potential_after), bool(success), bool(violation), float(proximity), float(remaining),
                   float(speed))
    return dict(zip(TERMS, t.tolist(), strict=True))


def total_reward(t: dict[str, float], w: RewardWeights) -> float:
    """Eq. 15 with our additions."""
    ego = w.w1 * t["r1_group_forming"] + w.w2 * t["r2_non_increasing"] + w.w3 * t["r3_time"]
    return (w.w_e * ego + w.w4 * t["r4_success"] + w.w_a * (w.w5 * t["r5_altruism"] + w.w_rep * t["r5_repulsion"])
            + w.w_effort * t["effort"] + w.w_smooth * t["smoothness"] + w.w_slot * t["slot_progress"]
            + w.w_prox * t["proximity"]
            + w.violation_penalty * t["violation"] + w.w_disp * t["displacement"] + w.w_arrive * t["arrival"])


def weight_vector(w: RewardWeights) -> np.ndarray:
    """Eq. 15 as weights on ``TERMS``: the terms (in ``TERMS`` order) dotted with it give ``total_reward``."""
    return np.array([w.w_e * w.w1, w.w_e * w.w2, w.w_e * w.w3, w.w4, w.w_a * w.w5, w.w_a * w.w_rep, w.w_effort,
                     w.w_smooth, w.w_slot, w.w_prox, w.violation_penalty, w.w_disp, w.w_arrive])
