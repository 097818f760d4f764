"""From tracked people to the group the policy sees: members (remembered while out of view), the conversation
centre, the o-space radius and the free slot, all in the odometry frame.

Pepper's camera sees 56 deg: at the free slot the members stand 60-90 deg to either side, so tracks of people
who leave the view are kept as *remembered* members (standing still where last seen) until their place comes
back into view, unoccluded and within detection range, and nobody is found there for ``forget_frames`` frames.
The group's geometry follows the simulator's model (``env.humans``): members on a circle around the centre,
the free slot in the middle of the widest gap on the robot's side. Three or more members give the circle by a
least-squares fit; two give only a chord, so the radius is the model's (``SocialParams.ospace_radius_for``)
and the centre lies on the robot's side of the chord (a group opening for a robot shifts its centre toward
it); a pair standing farther apart than the model's diameter is centred on its midpoint.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..env.humans import Group, widest_gap
from ..params import SocialParams
from ..perception.camera import PinholeCamera
from ..perception.tracker import Tracker, TrackerParams

BODY_HEIGHT = 1.14  # m: the point of a person checked against the view (torso middle, urdf/human.urdf)


@dataclasses.dataclass(frozen=True)
class GroupParams:
    """How long people are remembered and when they count as visible (ours)."""

    forget_frames: int = 5  # frames a remembered member's place is in clear view with nobody there
    same_person_m: float = 0.6  # a new track this close to a remembered member replaces it
    view_margin: float = 0.1  # fraction of the image width at each side where people are not expected whole
    max_range_m: float = 6.0  # people farther away are not expected to be detected
    person_halfwidth_m: float = 0.3  # for occlusion: a person hides what lies behind this half-width
    coast_tau_s: float = 1.0  # before a group is known, a remembered member's last velocity decays with this
    #                           time constant (once it is known, the social force model moves them)


@dataclasses.dataclass
class Member:
    """One person in the odometry frame (m, m/s, m^2); ``seen``: detected in the last frame (False for a
    coasting track or a remembered member)."""

    id: int
    pos: np.ndarray
    vel: np.ndarray
    cov: np.ndarray
    seen: bool = True
    unseen_in_view: int = 0


def group_circle(members: np.ndarray, robot_xy: np.ndarray, social: SocialParams) -> tuple[np.ndarray, float]:
    """Conversation centre (2,) and o-space radius (m) of members (n >= 2, (n, 2)); see the module docstring."""
    pts = np.asarray(members, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n < 2:
        raise ValueError(f"group_circle: {n} member(s); need 2 or more")
    if n == 2:
        mid, half = 0.5 * (pts[0] + pts[1]), 0.5 * float(np.hypot(*(pts[1] - pts[0])))
        r = social.ospace_radius_for(2)
        if half >= r or half < 1e-6:
            return mid, max(half, 1e-6)
        normal = np.array([pts[0, 1] - pts[1, 1], pts[1, 0] - pts[0, 0]]) / (2.0 * half)
        if normal @ (robot_xy - mid) < 0:
            normal = -normal
        return mid + math.sqrt(r * r - half * half) * normal, r
    # algebraic (Kasa) circle fit: x^2 + y^2 + D x + E y + F = 0
    a = np.column_stack([pts, np.ones(n)])
    b = -(pts ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = -0.5 * sol[:2]
    r2 = float(centre @ centre - sol[2])
    mean = pts.mean(axis=0)
    if not (r2 > 0 and math.sqrt(r2) <= 3.0 * social.ospace_radius_for(n + 1)):  # collinear: fall back
        return mean, float(np.hypot(*(pts - mean).T).mean())
    return centre, math.sqrt(r2)


class GroupModel:
    """The group's conversation centre and radius as the training model (``env.humans.Group``) defines them.

    Members re-form around a joining robot over seconds, while the model's centre moves with the robot at once
    (``Group.update_centre``: toward it by ``w / (n + 1)``, ``w`` the joining weight): the centre the policy was
    trained on is not the circle through the members while they move. So the centre before joining
    (``centre0``) is measured from the members while the robot is outside the joining zone (smoothed over
    frames), and held while it is inside; the joining shift and radius are the model's.
    """

    def __init__(self, social: SocialParams, smoothing: float = 0.3) -> None:
        self.social, self.smoothing = social, smoothing
        self.centre0: np.ndarray | None = None
        self.n = 0

    def reset(self) -> None:
        self.centre0, self.n = None, 0

    def update(self, members: np.ndarray, robot_xy: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Centre (2,), o-space radius (m) and joining weight for members (n >= 2, (n, 2)) and the robot."""
        s, n = self.social, len(members)
        measured, _ = group_circle(members, robot_xy, s)
        base = s.ospace_radius_for(n)
        if self.centre0 is None or n != self.n:
            self.centre0, self.n = measured, n
        elif float(np.hypot(*(robot_xy - measured))) >= base + s.join_margin:  # not joining: measure centre0
            self.centre0 = self.centre0 + self.smoothing * (measured - self.centre0)
        d = float(np.hypot(*(robot_xy - self.centre0)))
        w = min(1.0, max(0.0, (base + s.join_margin - d) / s.join_margin))
        joined = max(base, s.ospace_radius_for(n + 1))
        return self.centre0 + (w / (n + 1)) * (robot_xy - self.centre0), base + w * (joined - base), w


def free_slot(members: np.ndarray, centre: np.ndarray, radius: float, robot_xy: np.ndarray) -> np.ndarray:
    """The middle of the widest gap between members on the circle, ties broken toward the robot (as
    ``env.humans.Group.free_slot``)."""
    d = np.asarray(members, dtype=float).reshape(-1, 2) - centre
    toward = math.atan2(robot_xy[1] - centre[1], robot_xy[0] - centre[0])
    mid, _ = widest_gap(np.arctan2(d[:, 1], d[:, 0]), toward)
    return centre + radius * np.array([math.cos(mid), math.sin(mid)])


def _se2(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([[c, -s], [s, c]]), np.asarray(pose[:2], dtype=float)


class GroupTracker:
    """The Kalman tracker (ego-motion compensated) plus the memory of people out of view."""

    def __init__(self, camera: PinholeCamera, tracker: TrackerParams | None = None,
                 params: GroupParams | None = None, social: SocialParams | None = None) -> None:
        self.camera = camera
        self.tracker = Tracker(tracker)
        self.p = params or GroupParams()
        self.social = social or SocialParams()
        self.members: dict[int, Member] = {}
        self.centre0: np.ndarray | None = None  # the group's centre before joining (the loop's ``GroupModel``)

    def visible(self, xy_robot: np.ndarray, seen_robot: np.ndarray) -> np.ndarray:
        """Which robot-frame points (k, 2) a detector should find: in range, inside the image's middle part,
        and not hidden behind a nearer seen person (``seen_robot``, (m, 2))."""
        xy = np.asarray(xy_robot, dtype=float).reshape(-1, 2)
        pts = np.column_stack([xy, np.full(len(xy), BODY_HEIGHT)])
        u = self.camera.robot_to_pixel(pts)[:, 0]
        margin = self.p.view_margin * self.camera.width
        rng = np.hypot(xy[:, 0], xy[:, 1])
        ok = (np.isfinite(u) & (u >= margin) & (u <= self.camera.width - 1 - margin) & (rng <= self.p.max_range_m)
              & (xy[:, 0] > 0))
        if len(seen_robot):
            bearing, s_bearing = np.arctan2(xy[:, 1], xy[:, 0]), np.arctan2(seen_robot[:, 1], seen_robot[:, 0])
            s_rng = np.hypot(seen_robot[:, 0], seen_robot[:, 1])
            width = np.arctan2(self.p.person_halfwidth_m, np.maximum(rng, 1e-3))[:, None] + np.arctan2(
                self.p.person_halfwidth_m, np.maximum(s_rng, 1e-3))[None, :]
            gap = np.abs(np.remainder(bearing[:, None] - s_bearing[None, :] + math.pi, 2 * math.pi) - math.pi)
            hidden = ((s_rng[None, :] < rng[:, None] - 0.2) & (gap < width)).any(axis=1)
            ok &= ~hidden
        return ok

    def predict(self, seen: list[Member], gone: list[Member], robot_xy: np.ndarray, dt: float) -> None:
        """Move the members out of view by ``dt``: by the social force model around the group (as tracking with
        social-force motion priors does, Luber et al., ICRA 2010), or, before a group is known, with their last
        velocity decaying over ``coast_tau_s``."""
        if not gone:
            return
        if self.centre0 is None or len(seen) + len(gone) < 2:
            decay = math.exp(-dt / self.p.coast_tau_s)
            for m in gone:
                m.pos = m.pos + m.vel * (self.p.coast_tau_s * (1.0 - decay))  # exact for v(t) = v0 exp(-t / tau)
                m.vel = m.vel * decay
            return
        everyone = seen + gone
        group = Group(self.social, self.centre0, np.zeros(len(everyone)))
        group.pos = np.array([m.pos for m in everyone])
        group.vel = np.array([m.vel for m in everyone])
        group.step(np.asarray(robot_xy, dtype=float), dt)
        for m, q, v in zip(gone, group.pos[len(seen):], group.vel[len(seen):], strict=True):
            m.pos, m.vel = q, v

    def update(self, detections: np.ndarray, dt: float, pose: np.ndarray) -> list[Member]:
        """One frame's robot-frame ground detections (n, 2) taken at odometry ``pose``; returns the members."""
        states = self.tracker.update(np.asarray(detections, dtype=float).reshape(-1, 2), dt=dt, odom=pose)
        rot, t = _se2(pose)
        seen = {}
        for st in states:
            seen[st.id] = Member(st.id, rot @ st.position + t, rot @ st.velocity, rot @ st.covariance[:2, :2] @ rot.T,
                                 st.misses == 0)
        seen_robot = np.array([st.position for st in states]).reshape(-1, 2)
        gone = [m for k, m in self.members.items() if k not in seen]
        for m in gone:
            m.seen = False
        self.predict(list(seen.values()), gone, pose[:2], dt)
        if gone:
            local = (np.array([m.pos for m in gone]) - t) @ rot  # odometry -> robot frame
            in_view = self.visible(local, seen_robot)
            seen_xy = np.array([m.pos for m in seen.values()]).reshape(-1, 2)
            for m, vis in zip(gone, in_view, strict=True):
                m.unseen_in_view = m.unseen_in_view + 1 if vis else 0
                dup = len(seen_xy) and float(np.hypot(*(seen_xy - m.pos).T).min()) < self.p.same_person_m
                if dup or m.unseen_in_view >= self.p.forget_frames:
                    del self.members[m.id]
        self.members.update(seen)
        return list(self.members.values())
