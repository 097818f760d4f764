"""Safety shield: the last stage of the agent's action, keeping the robot out of the members' intimate zones.

It reads only the Vector observation (the same one the tracker produces on the robot), so the same function runs
in training, evaluation and deploy. For each member it computes the clearance between Pepper's footprint, taken
as its circumscribed circle (0.32 m: turning cannot bring a corner closer), and the member's body, and limits the
robot's closing speed on that member (relative to the member's own velocity) to
what the base can still brake away before ``clearance_min``: ``v_allow = sqrt(2 a (c - c_min))`` with ``a`` a
fraction of the base's acceleration limit. Anything faster toward the member is removed from the command; motion
past or away from it is untouched. NAOqi's own move protection (ALMotion's security distances) does the same on
the robot; the shield makes the simulated agent behave that way too, and lets the policy rely on it (it is on in
training). Ours; the paper has no such layer.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..params import RobotParams, SocialParams, _check, _positive
from .observation import decode_members
from .task import TaskParams


@dataclasses.dataclass(frozen=True)
class ShieldParams:
    """Limits of the shield (metres, seconds; ``from_env`` fills them from an env's parameters)."""

    clearance_min: float = 0.5  # m: intimate zone (0.45) + 0.05
    brake_accel: float = 0.2  # m/s^2: 2/3 of the NAOqi default 0.3, headroom for the command filter and latency
    max_speed: float = 0.35  # m/s: the action scale
    half_length: float = 0.24  # m: footprint half extents
    half_width: float = 0.215
    human_radius: float = 0.28

    def __post_init__(self) -> None:
        _positive("shield", self, "clearance_min", "brake_accel", "max_speed", "half_length", "half_width",
                  "human_radius")
        _check(self.brake_accel <= 0.55, "shield", "brake_accel", self.brake_accel, "<= 0.55 m/s^2 (Pepper's max)")

    @classmethod
    def from_env(cls, robot: RobotParams, social: SocialParams, task: TaskParams) -> ShieldParams:
        return cls(clearance_min=task.intimate_zone + 0.05, brake_accel=robot.max_accel * 2.0 / 3.0,
                   max_speed=robot.max_speed, half_length=robot.length / 2, half_width=robot.width / 2,
                   human_radius=social.human_radius)


def footprint_clearance(points: np.ndarray, heading: float, p: ShieldParams) -> tuple[np.ndarray, np.ndarray]:
    """Clearance (m) from the footprint's circumscribed circle at the origin to body circles at ``points`` (k, 2),
    and the unit directions (k, 2) toward each member; a lower bound of the box's clearance at any heading.

    The robot turns toward the group centre as it goes (up to 1 rad/s): measured from the box at its current
    heading, the clearance shrank by up to 0.1 m as a corner swung toward a member the robot was passing, and 13 %
    of the first real-group policy's ``mixed`` episodes ended in an intrusion (3 % with the circle;
    docs/decisions.md). ``heading`` is kept for the signature (the circle does not depend on it)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    dist = np.array([math.hypot(x, y) for x, y in points.tolist()])  # math's, as the compiled shield
    toward = points / np.maximum(dist, 1e-9)[:, None]
    return dist - math.hypot(p.half_length, p.half_width) - p.human_radius, toward


def shield_action(obs: np.ndarray, action: np.ndarray, p: ShieldParams) -> np.ndarray:
    """The action (approach frame, in [-1, 1]) with its excess closing speed on each member removed."""
    members, members_vel = decode_members(obs)
    a = np.asarray(action, dtype=np.float32)
    if len(members) == 0:
        return a
    heading = float(obs[39]) * math.pi
    clearance, toward = footprint_clearance(members, heading, p)
    v = a[:2].astype(float) * p.max_speed
    speed = math.hypot(v[0], v[1])
    if speed > p.max_speed:  # the base caps the planar speed at max_speed
        v *= p.max_speed / speed
    # nearest first; ties (a robot on a pair's bisector) in index order, as the kernel
    for j in np.argsort(clearance, kind="stable"):
        allow = math.sqrt(2.0 * p.brake_accel * max(float(clearance[j]) - p.clearance_min, 0.0))
        closing = float((v - members_vel[j]) @ toward[j])
        if closing > allow:
            v = v - (closing - allow) * toward[j]
    out = a.copy()
    out[:2] = np.clip(v / p.max_speed, -1.0, 1.0)
    return out


def shield_actions(obs: np.ndarray, actions: np.ndarray, p: ShieldParams) -> np.ndarray:
    """``shield_action`` for N observations (N, OBS_SIZE) and actions (N, A) at once (compiled, ``kernels``)."""
    from .kernels import shield

    a = np.ascontiguousarray(actions, dtype=np.float32)
    out = np.empty_like(a)
    shield(np.ascontiguousarray(obs, dtype=np.float32), a, p.clearance_min, p.brake_accel, p.max_speed,
           p.half_length, p.half_width, p.human_radius, out)
    return out


class SafetyShield:
    """``shield_action`` with fixed parameters (Pepper's defaults unless given), as ``TrainedPolicy`` applies it
    after its smoothing filter; any action shape, one observation."""

    def __init__(self, params: ShieldParams | None = None) -> None:
        self.params = params or ShieldParams()

    def __call__(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        return shield_action(np.asarray(obs).reshape(-1), np.asarray(action).reshape(-1), self.params).reshape(
            np.shape(action))
