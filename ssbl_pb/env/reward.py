"""Reward terms R1..R5 and effort (paper eqs. 11-15) as pure functions of one step's states.

Per step of ``dt`` seconds, with the robot moving by ``du`` through the field ``F`` evaluated at its position at
the start of the step and member j moving by ``du_j`` under its own total force ``F_j``:

* R1 (eq. 11, group forming): ``F . du`` (the line-integral increment).
* R2 (eq. 12, non-increasing energy): ``dt`` if the robot moves along the field (``v . F > 0``, the original
  code's test) else 0.
* R3 (eq. 13, time): ``-dt``; a step that ends the episode by a violation also pays the time it cut short
  (``remaining``), so that crashing early never costs less than waiting for the time-out (ours, issue 14).
* R4 (success bonus): 1 on the step that completes the approach.
* R5 (eq. 14, altruism): ``-sum_j F_j . du_j`` plus the original's repulsion term ``-sum_j |F_rep,j| dt``
  weighted by ``w_rep`` (how much the robot pushes the members).
* proximity (ours): ``-sum_j max(0, c_j - c'_j) ramp(c'_j)``, the metres by which the robot closes the clearance
  ``c`` to member j while within ``band`` of the intimate zone, weighted by ``ramp`` (0 at ``intimate + band``,
  1 at ``intimate``). Standing still costs nothing, driving at a member does (see ``proximity_cost``).
* effort: ``-|v|^2 dt``, and smoothness ``-|j| dt`` with ``j = (a_t - a_{t-1}) / dt`` the base's jerk (ours,
  see below; L1 so that small jerks still cost).

Total (eq. 15): ``w_e (w1 R1 + w2 R2 + w3 R3) + w4 R4 + w_a (w5 R5 + w_rep R5_rep) + w_effort E + w_smooth S
+ w_slot P + w_prox C - penalty``. The success bonus stands outside ``w_e`` as in the original code, which adds +1 on
success on top of the weighted per-step reward (eq. 15 writes it inside; with ``w_e = 0.0035`` it would be
negligible). ``P`` is the change of ``slot_potential`` (progress toward the free slot and braking near
it; ours) and ``penalty`` applies on a collision or an intrusion into a member's intimate zone.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..params import _check, _nonneg

TERMS = ("r1_group_forming", "r2_non_increasing", "r3_time", "r4_success", "r5_altruism", "r5_repulsion",
         "effort", "smoothness", "slot_progress", "proximity", "violation")


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


def route_distance(p: np.ndarray, slot: np.ndarray, centre: np.ndarray, keep_out: float) -> float:
    """Length of the shortest way from ``p`` to the free slot that enters the group only through the slot.

    The group is a disc of radius ``keep_out`` around its centre; the way goes around it (tangent, then arc) to
    the point of its rim on the slot's ray, then straight in. Inside the disc it is the straight distance plus
    the arc to the slot's ray, so cutting into the group elsewhere never shortens the way (ours: it makes the
    shaping lead around a group instead of through its members).
    """
    rel = (float(p[0] - centre[0]), float(p[1] - centre[1]))
    q = (float(slot[0] - centre[0]), float(slot[1] - centre[1]))
    r, rq = math.hypot(*rel), math.hypot(*q)
    dth = abs(math.remainder(math.atan2(rel[1], rel[0]) - math.atan2(q[1], q[0]), 2.0 * math.pi))
    R = max(keep_out, rq)
    if r < R:
        return math.hypot(rel[0] - q[0], rel[1] - q[1]) + R * dth
    beta = math.acos(R / r)
    if dth <= beta:  # the rim point on the slot's ray is in plain sight
        to_rim = math.sqrt(max(r * r + R * R - 2.0 * r * R * math.cos(dth), 0.0))
    else:
        to_rim = math.sqrt(r * r - R * R) + R * (dth - beta)
    return to_rim + (R - rq)


BRAKE_GAIN = 5.0  # s: slot_potential's weight on speed near the slot
BRAKE_RADIUS = 1.0  # m: within this distance of the slot


def slot_potential(distance: float, speed: float, brake_gain: float = BRAKE_GAIN,
                   brake_radius: float = BRAKE_RADIUS) -> float:
    """Potential of the robot's state for shaping (ours): minus the distance to the free slot, and minus its
    speed (times ``brake_gain`` seconds) within ``brake_radius`` of the slot, so arriving slowly pays. Its
    difference between steps is potential-based shaping (Ng et al. 1999): it does not change the optimum."""
    return -(distance + brake_gain * speed * max(0.0, 1.0 - distance / brake_radius))


def proximity_cost(clearance_before: np.ndarray, clearance_after: np.ndarray, intimate: float,
                   band: float) -> float:
    """Metres the robot closed on members near their intimate zone this step, each weighted by how deep it is in
    the ``band`` beyond the zone (linear: 0 at ``intimate + band``, 1 at ``intimate``); >= 0.

    Ours. The violation penalty alone is a cliff: a policy that circles a group along the intimate zone's edge
    learns nothing until it falls over it. This cost is graded and charges only closing in, so standing at a
    slot between two near neighbours costs (almost) nothing, while grazing a member at full speed does. Closing
    counts whoever moves; members settling around a still robot close at most a few cm per second.
    """
    after = np.asarray(clearance_after)
    closed = np.maximum(np.asarray(clearance_before) - after, 0.0)
    depth = np.minimum(np.maximum((intimate + band - after) * (1.0 / band), 0.0), 1.0)
    return float(closed @ depth)


def reward_terms(
    robot_force: np.ndarray,
    robot_du: np.ndarray,
    member_forces: np.ndarray,
    member_du: np.ndarray,
    member_repulsion: np.ndarray,
    dt: float,
    accel: np.ndarray,
    prev_accel: np.ndarray,
    potential_before: float,
    potential_after: float,
    success: bool,
    violation: bool,
    proximity: float = 0.0,
    remaining: float = 0.0,
) -> dict[str, float]:
    """Unweighted terms of one step (see the module docstring for each formula and its unit); ``remaining`` is
    the episode's time left (s) after this step, charged to R3 when it ends in a violation."""
    fx, fy = float(robot_force[0]), float(robot_force[1])
    dx, dy = float(robot_du[0]), float(robot_du[1])
    along = fx * dx + fy * dy  # F . du, and v . F has the same sign
    jx, jy = float(accel[0] - prev_accel[0]), float(accel[1] - prev_accel[1])
    rep = member_repulsion
    return {
        "r1_group_forming": along,
        "r2_non_increasing": dt if along > 0.0 else 0.0,
        "r3_time": -(dt + remaining) if violation else -dt,
        "r4_success": 1.0 if success else 0.0,
        "r5_altruism": -float((member_forces * member_du).sum()),
        "r5_repulsion": -float(np.hypot(rep[:, 0], rep[:, 1]).sum()) * dt,
        "effort": -(dx * dx + dy * dy) / dt,
        "smoothness": -math.hypot(jx, jy),
        "slot_progress": potential_after - potential_before,
        "proximity": -proximity,
        "violation": -1.0 if violation else 0.0,
    }


def total_reward(t: dict[str, float], w: RewardWeights) -> float:
    """Eq. 15 with our additions."""
    ego = w.w1 * t["r1_group_forming"] + w.w2 * t["r2_non_increasing"] + w.w3 * t["r3_time"]
    return (w.w_e * ego + w.w4 * t["r4_success"] + w.w_a * (w.w5 * t["r5_altruism"] + w.w_rep * t["r5_repulsion"])
            + w.w_effort * t["effort"] + w.w_smooth * t["smoothness"] + w.w_slot * t["slot_progress"]
            + w.w_prox * t["proximity"]
            + w.violation_penalty * t["violation"])


def weight_vector(w: RewardWeights) -> np.ndarray:
    """Eq. 15 as weights on ``TERMS``: the terms (in ``TERMS`` order) dotted with it give ``total_reward``."""
    return np.array([w.w_e * w.w1, w.w_e * w.w2, w.w_e * w.w3, w.w4, w.w_a * w.w5, w.w_a * w.w_rep, w.w_effort,
                     w.w_smooth, w.w_slot, w.w_prox, w.violation_penalty])
