"""Safety shield: the last stage of the agent's action, keeping the robot out of the members' intimate zones.

It reads only the Vector observation (the same one the tracker produces on the robot), so the same function runs in
training, evaluation and deploy. For each member it computes the clearance between Pepper's footprint, taken as its
circumscribed circle (0.32 m: turning cannot bring a corner closer), and the member's body, and limits the robot's
closing speed on that member (relative to the member's own velocity) to what the base can still brake away before
``clearance_min``: ``v_allow = sqrt(2 a (c - c_min))`` with ``a`` a fraction of the base's acceleration limit.
Anything faster toward the member is removed from the command; motion past or away from it is untouched. With the
range scan in the observation, each ray's end is treated alike as a standing obstacle point, braked for before
``obstacle_clearance_min``. NAOqi's own move protection (ALMotion's security distances) does the same on the robot;
the shield makes the simulated agent behave that way too, and lets the policy rely on it (it is on in training).
Ours; the paper has no such layer.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numba import njit

from ..params import RobotParams, SocialParams, WorldParams, _check, _positive
from .layouts import slot_keep
from .observation import (
    BASE_SIZE,
    CENTRE_X,
    CENTRE_Y,
    MAX_MEMBERS,
    MEMBER_FIELDS,
    MEMBER_PRESENT,
    MEMBER_VX,
    MEMBER_VY,
    MEMBER_X,
    MEMBER_Y,
    MEMBERS,
    OSPACE_RADIUS,
    POS_SCALE,
    SCAN_RANGE,
    SLOT_X,
    SLOT_Y,
    VEL_FORWARD,
    VEL_LEFT,
)
from .task import TaskParams

# m from the place shown in the observation within which the place's clearance (``place_clearance``) holds
# fully, and beyond which not at all (linear between): the task's slot tolerance, and twice it (ours)
PLACE_NEAR, PLACE_FAR = 0.3, 0.6
# ... and where the range scan's nearest point lies beyond ``ROOM_FAR`` (not at all where it is nearer than
# ``ROOM_NEAR``, linear between), the same from ``CLEARANCE_NEAR`` of the place out to ``CLEARANCE_FAR``: the
# passing clearance. Ours: held within 0.6 m only, the robot rounding a pair's member toward its place passed them
# at the 0.5 m line and pushed them 0.25-0.38 m in 10 % of default starts (members displaced 0.087 m against the
# SFFM's 0.073). Swept on 200 starts per scenario (docs/decisions.md, "Safety shield"): 1.2 / 1.6 m gives 0.062 m;
# without the scan's gate it cost 17 points in the small map room (ways between a member and the furniture); 2.0 /
# 2.5 m cost 4.5 points of mixed
CLEARANCE_NEAR, CLEARANCE_FAR = 1.2, 1.6
ROOM_NEAR, ROOM_FAR = 1.0, 1.5


@njit(cache=True)
def scan_min(obs: np.ndarray) -> float:
    """Metres to the nearest thing the observation's range scan sees (``SCAN_RANGE`` when none or no scan)."""
    d = SCAN_RANGE
    for k in range(BASE_SIZE, obs.shape[0]):
        d = min(d, float(obs[k]) * SCAN_RANGE)
    return d


# which rule changed a command (bit flags; ``shield_row`` returns them, ``rule_names`` spells them)
RULE_MEMBERS = 1  # closing speed on a member braked (or the command scaled for one)
RULE_OBSTACLES = 2  # closing speed on what the range scan sees braked (or scaled)
RULE_SLIDE = 4  # a command stopped by an obstacle turned to slide along it
RULE_VELOCITY = 8  # the base's own velocity braked first (it already closed too fast)
RULE_OSPACE = 16  # kept out of the o-space short of the place's ring
RULE_PLACE = 32  # speed capped near the place (the arrival)
RULES = ("members", "obstacles", "slide", "velocity", "ospace", "place")


@dataclasses.dataclass(frozen=True)
class ShieldParams:
    """Limits of the shield (metres, seconds; ``from_env`` fills them from an env's parameters)."""

    clearance_min: float = 0.5  # m: intimate zone (0.45) + 0.05
    brake_accel: float = 0.2  # m/s^2: 2/3 of the NAOqi default 0.3, headroom for the command filter and latency
    max_speed: float = RobotParams.max_speed  # m/s: the action scale
    half_length: float = RobotParams.length / 2  # m: footprint half extents
    half_width: float = RobotParams.width / 2
    human_radius: float = SocialParams.human_radius
    obstacle_clearance_min: float = 0.1  # m from walls and obstacles (the scan): room to pass between desks
    base_accel: float = RobotParams.max_accel  # m/s^2: the base's own limit (NAOqi default), over one control period:
    control_period: float = WorldParams.dt  # s (the env's and the deploy loop's 10 Hz)
    place_clearance: float = 0.0  # m kept from every member near the place (0: off; ``from_env``'s ``at_place``)
    place_arrival_speed: float = 0.0  # m/s the approach slows to at the place's tolerance (0: off; ``at_place``)
    ospace_keep_out: bool = False  # keep out of the group's o-space short of the place's ring (``at_place``)

    def __post_init__(self) -> None:
        _positive("shield", self, "clearance_min", "brake_accel", "max_speed", "half_length", "half_width",
                  "human_radius", "obstacle_clearance_min", "base_accel", "control_period")
        _check(self.place_clearance >= 0, "shield", "place_clearance", self.place_clearance, ">= 0")
        _check(0 <= self.place_arrival_speed <= self.max_speed, "shield", "place_arrival_speed",
               self.place_arrival_speed, f"in [0, max_speed = {self.max_speed}]")
        _check(self.brake_accel <= 0.55, "shield", "brake_accel", self.brake_accel, "<= 0.55 m/s^2 (Pepper's max)")
        _check(isinstance(self.ospace_keep_out, bool), "shield", "ospace_keep_out", self.ospace_keep_out,
               "true or false")

    @classmethod
    def from_env(cls, robot: RobotParams, social: SocialParams, task: TaskParams,
                 at_place: bool = False) -> ShieldParams:
        """The shield of an env's robot. ``at_place`` (a policy's config ``shield_at_place``): near its place it
        keeps the place's own clearance from every member (``layouts.slot_keep`` between centres: 0.6 m between
        the member's body and the footprint's circle), instead of the intimate zone plus 0.05; and it slows the
        approach to half the success rule's stop speed where the place's tolerance begins (``place_speed_cap``); and
        it keeps the robot's centre out of the o-space (``ospace_keep_out``, ``OSPACE_MARGIN``).

        Ours: braking for 0.5 m, the shield ended the approach 5-10 cm past the place, inside the
        members' 1.2 m repulsion zone, and they stepped away (members displaced 0.17 m against the SFFM's 0.07).
        Kept everywhere, 0.6 m also blocked ways round a group's members (10 points of `mixed`). The speed cap
        (ours): the policy braked at the base's limit into the place and arrived at
        0.087 m/s, the success rule's 0.1 less one period's braking, however its reward priced the arrival."""
        return cls(clearance_min=task.intimate_zone + 0.05, brake_accel=robot.max_accel * 2.0 / 3.0,
                   max_speed=robot.max_speed, half_length=robot.length / 2, half_width=robot.width / 2,
                   human_radius=social.human_radius, base_accel=robot.max_accel,
                   place_clearance=slot_keep(social, robot.reach, task.intimate_zone, task.route_margin)
                   - social.human_radius - robot.reach if at_place else 0.0,
                   place_arrival_speed=task.stop_speed / 2 if at_place else 0.0, ospace_keep_out=at_place)

    @classmethod
    def of(cls, env: Any, at_place: bool = False) -> ShieldParams:
        """``from_env`` of anything holding ``robot_params``, ``social`` and ``task`` (an env's core, a batched
        env, deploy's ``Setup``): the one builder of a robot's shield."""
        return cls.from_env(env.robot_params, env.social, env.task, at_place)


@njit(cache=True)
def circle_clearance(px: float, py: float, reach: float, human_radius: float) -> tuple[float, float, float]:
    """Clearance (m) from the footprint's circumscribed circle (radius ``reach``) at the origin to a body circle
    at (px, py), and the unit direction toward it: a lower bound of the box's clearance at any heading.

    The robot turns toward the group centre as it goes (up to 1 rad/s): measured from the box at its current
    heading, the clearance shrank by up to 0.1 m as a corner swung toward a member the robot was passing, and 13 %
    of the first real-group policy's ``mixed`` episodes ended in an intrusion (3 % with the circle;
    docs/decisions.md)."""
    dist = math.hypot(px, py)
    norm = max(dist, 1e-9)
    return dist - reach - human_radius, px / norm, py / norm


def footprint_clearance(points: np.ndarray, heading: float, p: ShieldParams, radius: float | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """``circle_clearance`` of body circles at ``points`` (k, 2) (``radius``, default ``human_radius``; 0: the
    points themselves): clearances (k,) and directions (k, 2). ``heading`` is kept for the signature (the circle
    does not depend on it)."""
    reach = math.hypot(p.half_length, p.half_width)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    radius = p.human_radius if radius is None else radius
    out = [circle_clearance(px, py, reach, radius) for px, py in points.tolist()]
    return np.array([o[0] for o in out]), np.array([o[1:] for o in out]).reshape(-1, 2)


@njit(cache=True)
def _brake(vx: float, vy: float, ux: float, uy: float, other_vx: float, other_vy: float, clearance: float,
           clearance_min: float, brake_accel: float) -> tuple[float, float]:
    """(vx, vy) with its closing speed on something ``clearance`` away in the unit direction (ux, uy), moving at
    (other_vx, other_vy), cut to ``sqrt(2 a (c - c_min))``."""
    allow = math.sqrt(2.0 * brake_accel * max(clearance - clearance_min, 0.0))
    closing = (vx - other_vx) * ux + (vy - other_vy) * uy
    if closing > allow:
        vx, vy = vx - (closing - allow) * ux, vy - (closing - allow) * uy
    return vx, vy


def brake_closing(velocity: np.ndarray, points: np.ndarray, clearance_min: np.ndarray, p: ShieldParams,
                  radius: float | None = None) -> np.ndarray:
    """The body velocity (vx, vy) with its closing speed on each standing body circle at robot-frame ``points``
    (k, 2) (``radius`` as ``footprint_clearance``) cut to ``sqrt(2 a (c - c_min))``, each point with its own
    ``clearance_min`` (k,), nearest first (the shield's member rule, ``_brake``, outside the observation)."""
    vx, vy = (float(v) for v in np.asarray(velocity, dtype=float)[:2])
    clear, toward = footprint_clearance(points, 0.0, p, radius)
    for j in np.argsort(clear):
        vx, vy = _brake(vx, vy, float(toward[j, 0]), float(toward[j, 1]), 0.0, 0.0, float(clear[j]),
                        float(clearance_min[j]), p.brake_accel)
    return np.array([vx, vy])


def brake_returns(velocity: np.ndarray, points: np.ndarray, clearance_min: np.ndarray | float, p: ShieldParams,
                  latency: float = 0.0, radius: float = 0.0) -> np.ndarray:
    """The body velocity (vx, vy) braked for range returns at robot-frame ``points`` (k, 2): standing points on
    whatever the lasers and sonars hit (a person's legs, a wall; or circles of ``radius``), each one's clearance
    taken from the footprint's circle, its closing speed cut to ``sqrt(2 a (c - c_min))`` (``brake_closing``,
    nearest first), ``c_min`` (per point, or one) raised by what the robot covers in ``latency`` s (the returns'
    age); then scaled down until every point's limit holds at once (braking for one side of a passage may add speed
    toward the other; every limit is >= 0, so a slower motion the same way keeps them all)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    v = np.asarray(velocity, dtype=float)[:2]
    c_min = np.broadcast_to(np.asarray(clearance_min, dtype=float), (len(pts),)) + math.hypot(*v) * latency
    out = brake_closing(v, pts, c_min, p, radius=radius)
    clear, toward = footprint_clearance(pts, 0.0, p, radius=radius)
    allow, closing = np.sqrt(2.0 * p.brake_accel * np.maximum(clear - c_min, 0.0)), toward @ out
    over = closing > allow + 1e-12
    return out * float(np.min(allow[over] / closing[over])) if over.any() else out


RAY_PASSES = 4  # rounds of braking sector by sector: each keeps the motion along the obstacles (no dead stop)


@njit(cache=True)
def _scale_to_limits(obs: np.ndarray, vx: float, vy: float, clear: np.ndarray, toward: np.ndarray, reach: float,
                     clearance_min: float, brake_accel: float, obstacle_clearance_min: float
                     ) -> tuple[float, float, int]:
    """(vx, vy) scaled down until no ray's and no member's closing speed exceeds its limit. Braking for each in
    turn is not enough where they stand on two sides (a passage between desks, or between a member and a desk):
    removing the speed toward one side adds speed toward the other, and 2.5 % of the meeting room's episodes ended
    on an obstacle the scan saw. Every ray's limit is >= 0 (obstacles stand still), so a slower motion in the same
    direction keeps them all; a member walking at the robot may ask for more than stopping (then the robot stops).
    Runs after ``RAY_PASSES`` rounds of braking, which leave little or nothing to scale. Also returns the rule
    (``RULE_MEMBERS`` or ``RULE_OBSTACLES``) whose limit set the scale, 0 when nothing was scaled."""
    rays = obs.shape[0] - BASE_SIZE
    scale = 1.0
    rule = 0
    for k in range(rays):
        r = float(obs[BASE_SIZE + k])
        if r >= 0.999:
            continue
        a = 2.0 * math.pi * k / rays
        d, ux, uy = circle_clearance(r * SCAN_RANGE * math.cos(a), r * SCAN_RANGE * math.sin(a), reach, 0.0)
        closing = vx * ux + vy * uy
        allow = math.sqrt(2.0 * brake_accel * max(d - obstacle_clearance_min, 0.0))
        if closing > allow and allow / closing < scale:
            scale, rule = allow / closing, RULE_OBSTACLES
    for j in range(clear.shape[0]):
        if clear[j] == np.inf:
            continue
        b = MEMBERS + MEMBER_FIELDS * j
        ux, uy = toward[j, 0], toward[j, 1]
        closing, theirs = vx * ux + vy * uy, float(obs[b + MEMBER_VX]) * ux + float(obs[b + MEMBER_VY]) * uy
        allow = math.sqrt(2.0 * brake_accel * max(clear[j] - clearance_min, 0.0))
        if closing - theirs > allow and closing > 0.0 and max(allow + theirs, 0.0) / closing < scale:
            scale, rule = max(allow + theirs, 0.0) / closing, RULE_MEMBERS
    return vx * scale, vy * scale, rule


@njit(cache=True)
def _shielded(obs: np.ndarray, vx: float, vy: float, clear: np.ndarray, toward: np.ndarray, reach: float,
              clearance_min: float, brake_accel: float, obstacle_clearance_min: float
              ) -> tuple[float, float, bool, int]:
    """(vx, vy) braked for the members (nearest first) and for the scan's sectors, in up to ``RAY_PASSES`` rounds,
    then scaled to keep every member's and sector's limit; whether anything was near enough to brake for; and
    the rules (``RULE_MEMBERS``, ``RULE_OBSTACLES``) that changed it."""
    acted = False
    rules = 0
    rays = obs.shape[0] - BASE_SIZE
    order = np.argsort(clear, kind="mergesort")
    for _ in range(RAY_PASSES):
        before = (vx, vy)
        for j in order:
            if clear[j] == np.inf:
                break
            b = MEMBERS + MEMBER_FIELDS * j
            nx, ny = _brake(vx, vy, toward[j, 0], toward[j, 1], float(obs[b + MEMBER_VX]), float(obs[b + MEMBER_VY]),
                            clear[j],
                            clearance_min, brake_accel)
            if nx != vx or ny != vy:
                rules |= RULE_MEMBERS
            vx, vy = nx, ny
            acted = True
        for k in range(rays):
            r = float(obs[BASE_SIZE + k])
            if r >= 0.999:  # nothing within range
                continue
            a = 2.0 * math.pi * k / rays
            d, ux, uy = circle_clearance(r * SCAN_RANGE * math.cos(a), r * SCAN_RANGE * math.sin(a), reach, 0.0)
            nx, ny = _brake(vx, vy, ux, uy, 0.0, 0.0, d, obstacle_clearance_min, brake_accel)
            if nx != vx or ny != vy:
                rules |= RULE_OBSTACLES
            vx, vy = nx, ny
            acted = True
        if (vx, vy) == before:
            break
    if acted:
        vx, vy, scaled = _scale_to_limits(obs, vx, vy, clear, toward, reach, clearance_min, brake_accel,
                                          obstacle_clearance_min)
        rules |= scaled
    return vx, vy, acted, rules


BRAKE_FIRST = 0.01  # m/s a velocity may exceed the limits before the shield brakes it first (``_over_limits``)


@njit(cache=True)
def _over_limits(obs: np.ndarray, vx: float, vy: float, clear: np.ndarray, toward: np.ndarray, reach: float,
                 clearance_min: float, brake_accel: float, obstacle_clearance_min: float) -> bool:
    """Whether (vx, vy) closes on a member or a sector faster than its limit (by more than ``BRAKE_FIRST``)."""
    tx, ty, _ = _scale_to_limits(obs, vx, vy, clear, toward, reach, clearance_min, brake_accel,
                                 obstacle_clearance_min)
    return math.hypot(vx - tx, vy - ty) > BRAKE_FIRST


SLIDE_ANGLES = (math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)  # tried in turn when an obstacle stops it


@njit(cache=True)
def shield_row(obs: np.ndarray, action: np.ndarray, out: np.ndarray, clearance_min: float, brake_accel: float,
               max_speed: float, half_length: float, half_width: float, human_radius: float,
               obstacle_clearance_min: float, accel_step: float, place_clearance: float,
               place_arrival_speed: float, ospace_keep_out: float) -> int:
    """The action (approach frame, in [-1, 1]) with its excess closing speed on each member removed, into ``out``;
    returns the rules that changed it (``RULE_*`` bit flags, 0 when it passed unchanged but for the speed cap):
    members nearest first, each limiting the closing speed to ``sqrt(2 a (c - c_min))``; then the same for every
    ray of the range scan that ends within its range (observations longer than ``BASE_SIZE``), in up to
    ``RAY_PASSES`` rounds of both (each braking may give back speed toward an earlier member or sector; a few rounds
    settle on a motion along them), and finally the speed scaled down to keep every limit at once
    (``_scale_to_limits``: a safety net that, alone, stopped the robot dead beside a desk).

    A command aimed straight at an obstacle keeps nothing, and a deterministic policy asks for it again at the
    next step: the robot stood still until its time ran out (most time-outs in the map rooms). So when the scan
    (not a member) takes more than 90 % of a command of at least a third of the top speed, the command turned by
    45 deg, then 90 deg, to either side is shielded instead, the one going most the way asked for if it keeps a
    quarter of the speed: the robot slides along the obstacle as a person would.

    Near the place shown in the observation (its entries 0-1), ``clearance_min`` rises to ``place_clearance``
    (when larger): fully within ``PLACE_NEAR``, linearly less out to ``PLACE_FAR``, and where the scan sees
    nothing near (``ROOM_NEAR``, ``ROOM_FAR``) likewise from ``CLEARANCE_NEAR`` out to ``CLEARANCE_FAR``; and with
    ``place_arrival_speed`` the speed is capped as it nears that place (``place_speed_cap``). With
    ``ospace_keep_out`` the closing speed on the conversation centre (entries 2-3) is braked, like a member's, to
    keep the robot's centre ``OSPACE_MARGIN`` inside the o-space radius (entry 4) at most."""
    out[:] = action
    to_place = math.hypot(float(obs[SLOT_X]), float(obs[SLOT_Y])) * POS_SCALE
    near = min(max((PLACE_FAR - to_place) / (PLACE_FAR - PLACE_NEAR), 0.0), 1.0)
    room = min(max((scan_min(obs) - ROOM_NEAR) / (ROOM_FAR - ROOM_NEAR), 0.0), 1.0)
    wide = min(max((CLEARANCE_FAR - to_place) / (CLEARANCE_FAR - CLEARANCE_NEAR), 0.0), 1.0) * room
    clearance_min += max(place_clearance - clearance_min, 0.0) * max(near, wide)
    reach = math.hypot(half_length, half_width)
    clear = np.full(MAX_MEMBERS, np.inf)
    toward = np.zeros((MAX_MEMBERS, 2))
    for j in range(MAX_MEMBERS):
        b = MEMBERS + MEMBER_FIELDS * j
        if float(obs[b + MEMBER_PRESENT]) > 0.5:
            clear[j], toward[j, 0], toward[j, 1] = circle_clearance(float(obs[b + MEMBER_X]) * POS_SCALE,
                                                                    float(obs[b + MEMBER_Y]) * POS_SCALE, reach,
                                                                    human_radius)
    vx, vy = float(action[0]) * max_speed, float(action[1]) * max_speed
    speed = math.hypot(vx, vy)
    if speed > max_speed:  # the base caps the planar speed at max_speed
        vx, vy = vx * (max_speed / speed), vy * (max_speed / speed)
        speed = max_speed
    sx, sy, acted, rules = _shielded(obs, vx, vy, clear, toward, reach, clearance_min, brake_accel,
                                     obstacle_clearance_min)
    if acted and obs.shape[0] > BASE_SIZE and speed > max_speed / 3 and math.hypot(sx, sy) < 0.1 * speed:
        mx, my, _, _ = _shielded(obs[:BASE_SIZE], vx, vy, clear, toward, reach, clearance_min, brake_accel,
                                 obstacle_clearance_min)
        if math.hypot(mx, my) >= 0.1 * speed:  # the members allow it: the obstacles stopped it
            best, slid = -np.inf, 0
            for ang in SLIDE_ANGLES:
                c, s = math.cos(ang), math.sin(ang)
                tx, ty, _, turned = _shielded(obs, c * vx - s * vy, s * vx + c * vy, clear, toward, reach,
                                              clearance_min, brake_accel, obstacle_clearance_min)
                gain = tx * vx + ty * vy
                if math.hypot(tx, ty) >= 0.25 * speed and gain > best:
                    best, sx, sy, slid = gain, tx, ty, RULE_SLIDE | turned
            rules |= slid
    if acted:
        # the base reaches a command at its acceleration limit: while its velocity already closes faster than it
        # can brake for, a turned command spends that limit sideways and the robot runs on into what it was
        # closing on (a desk's corner in 1 of 1,000 lab episodes). When one period toward the command would not
        # bring the velocity within the limits, the velocity itself is shielded: the command then differs from
        # it only by braking, and all of the acceleration goes to that.
        cx, cy = float(obs[VEL_FORWARD]) * max_speed, float(obs[VEL_LEFT]) * max_speed
        if _over_limits(obs, cx, cy, clear, toward, reach, clearance_min, brake_accel, obstacle_clearance_min):
            dx, dy = sx - cx, sy - cy
            change = math.hypot(dx, dy)
            if change > accel_step:
                dx, dy = dx * accel_step / change, dy * accel_step / change
            if _over_limits(obs, cx + dx, cy + dy, clear, toward, reach, clearance_min, brake_accel,
                            obstacle_clearance_min):
                sx, sy, _, braked = _shielded(obs, cx, cy, clear, toward, reach, clearance_min, brake_accel,
                                              obstacle_clearance_min)
                rules |= RULE_VELOCITY | braked
        out[0] = min(max(sx / max_speed, -1.0), 1.0)
        out[1] = min(max(sy / max_speed, -1.0), 1.0)
    if ospace_keep_out > 0.0:
        cx, cy = float(obs[CENTRE_X]) * POS_SCALE, float(obs[CENTRE_Y]) * POS_SCALE
        to_centre = math.hypot(cx, cy)
        if to_centre > 1e-6:
            ox, oy = float(out[0]) * max_speed, float(out[1]) * max_speed
            bx, by = _brake(ox, oy, cx / to_centre, cy / to_centre, 0.0, 0.0,
                            to_centre - (float(obs[OSPACE_RADIUS]) * POS_SCALE - OSPACE_MARGIN), 0.0, brake_accel)
            if bx != ox or by != oy:
                rules |= RULE_OSPACE
            out[0], out[1] = bx / max_speed, by / max_speed
    if place_arrival_speed > 0.0 and clear.min() >= clearance_min - CAP_SLACK:
        cap = place_speed_cap(to_place, place_arrival_speed, brake_accel) / max_speed
        norm = math.hypot(float(out[0]), float(out[1]))
        if norm > cap:
            out[0], out[1] = out[0] * (cap / norm), out[1] * (cap / norm)
            rules |= RULE_PLACE
    return rules


# m the robot's centre may come inside the o-space radius: the slot tolerance, so a place on the ring stays within
# reach. Ours: without, 6 % of `mixed` starts (L-shaped and side-by-side pairs, whose ring is wider) ended with the
# robot inside the o-space, 0.3-0.6 m inward of its place, until the time-out
OSPACE_MARGIN = PLACE_NEAR
CAP_SLACK = 0.01  # m: the speed cap holds only where the robot keeps the clearance asked of it, less this


@njit(cache=True)
def place_speed_cap(to_place: float, arrival_speed: float, brake_accel: float) -> float:
    """Top speed (m/s) at ``to_place`` metres from the place: ``sqrt(v_a^2 + 2 a (d - PLACE_NEAR))``, braking at
    ``a`` to reach ``v_a`` where the place's tolerance (``PLACE_NEAR``) begins, and ``v_a`` within it. With
    Pepper's 0.2 m/s^2 it binds only within 0.6 m of the place (0.35 m/s there)."""
    return math.sqrt(arrival_speed * arrival_speed + 2.0 * brake_accel * max(to_place - PLACE_NEAR, 0.0))


@njit(cache=True)
def _shield_rows(obs: np.ndarray, actions: np.ndarray, out: np.ndarray, rules: np.ndarray, clearance_min: float,
                 brake_accel: float, max_speed: float, half_length: float, half_width: float, human_radius: float,
                 obstacle_clearance_min: float, accel_step: float, place_clearance: float,
                 place_arrival_speed: float, ospace_keep_out: float) -> None:
    for i in range(obs.shape[0]):
        rules[i] = shield_row(obs[i], actions[i], out[i], clearance_min, brake_accel, max_speed, half_length,
                              half_width, human_radius, obstacle_clearance_min, accel_step, place_clearance,
                              place_arrival_speed, ospace_keep_out)


def shield_actions(obs: np.ndarray, actions: np.ndarray, p: ShieldParams) -> np.ndarray:
    """``shield_row`` for N observations (N, OBS_SIZE) and actions (N, A) at once."""
    return shield_actions_explained(obs, actions, p)[0]


def shield_actions_explained(obs: np.ndarray, actions: np.ndarray, p: ShieldParams) -> tuple[np.ndarray, np.ndarray]:
    """``shield_actions`` and, per row, the rules that changed the action (``RULE_*`` flags, int (N,))."""
    a = np.ascontiguousarray(actions, dtype=np.float32)
    out, rules = np.empty_like(a), np.zeros(len(a), dtype=np.int64)
    _shield_rows(np.ascontiguousarray(obs, dtype=np.float32), a, out, rules, *_limits(p))
    return out, rules


def shield_action(obs: np.ndarray, action: np.ndarray, p: ShieldParams) -> np.ndarray:
    """``shield_row`` for one observation and action."""
    return shield_actions(np.asarray(obs)[None], np.asarray(action).reshape(1, -1), p)[0]


def rule_names(rules: int) -> list[str]:
    """The names (``RULES``) of the rules set in ``rules`` (``RULE_*`` flags)."""
    return [name for k, name in enumerate(RULES) if int(rules) & (1 << k)]


def _limits(p: ShieldParams) -> tuple[float, ...]:
    return (p.clearance_min, p.brake_accel, p.max_speed, p.half_length, p.half_width, p.human_radius,
            p.obstacle_clearance_min, p.base_accel * p.control_period, p.place_clearance, p.place_arrival_speed,
            float(p.ospace_keep_out))


@dataclasses.dataclass(frozen=True)
class ShieldRecord:
    """What the shield did to its last input: the actions before and after it (one row, or a batch's rows) and
    the rules (``RULE_*`` flags, one per row; 0: passed unchanged)."""

    before: np.ndarray
    after: np.ndarray
    rules: np.ndarray

    def changed(self) -> np.ndarray:
        """Per row, whether a rule changed the action (bool (N,))."""
        return self.rules != 0

    def correction(self) -> np.ndarray:
        """Per row, how far a rule moved the action (norm, action units; not the base's cap of the planar speed at 1,
        which a changed action gets too); 0 where none changed it."""
        b = self.before.reshape(len(self.rules), -1).astype(float)
        b[:, :2] /= np.maximum(np.linalg.norm(b[:, :2], axis=1, keepdims=True), 1.0)
        return np.where(self.changed(), np.linalg.norm(self.after.reshape(b.shape) - b, axis=1), 0.0)

    def row(self, i: int = 0) -> dict[str, Any] | None:
        """Row ``i`` for a log: before, after and the rules' names; None where the shield left it alone."""
        if not self.rules[i]:
            return None
        before, after = self.before.reshape(len(self.rules), -1)[i], self.after.reshape(len(self.rules), -1)[i]
        return {"before": before.tolist(), "after": after.tolist(), "rules": rule_names(self.rules[i])}


class SafetyShield:
    """``shield_action`` with fixed parameters (Pepper's defaults unless given), as ``TrainedPolicy`` applies it after
    its smoothing filter: one observation (OBS_SIZE,) with one action, or a batch (N, OBS_SIZE) with (N, A) actions,
    every row shielded. ``last`` records what it did to the last call (``ShieldRecord``): the evaluation's
    intervention rate, deploy's log, training's ``shield_penalty``."""

    def __init__(self, params: ShieldParams | None = None) -> None:
        self.params = params or ShieldParams()
        self.last: ShieldRecord | None = None

    def __call__(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        action, rows = np.asarray(action), np.asarray(obs).reshape(-1, np.shape(obs)[-1])
        if action.size % len(rows):
            raise ValueError(f"shield: {len(rows)} observations for actions of shape {action.shape}")
        out, rules = shield_actions_explained(rows, action.reshape(len(rows), -1), self.params)
        self.last = ShieldRecord(action.astype(np.float32, copy=True), out.reshape(action.shape), rules)
        return self.last.after
