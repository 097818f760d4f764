"""From tracked people to the group the policy sees: members (remembered while out of view), the conversation
centre, the o-space radius and the free slot, all in the odometry frame.

Pepper's camera sees 56 deg: at the free slot the members stand 60-90 deg to either side, so tracks of people
who leave the view are kept as *remembered* members, standing where last estimated (``GroupTracker.hold``), until
their place comes back into view, unoccluded and within detection range, and nobody is found there for
``forget_frames`` frames.
The group's geometry is the simulator's (``core.humans.measured_group``: the centre, the o-space radius, the
joining weight and the free slot come from the same functions the env steps), spawned where the members stood
before the robot came to join (their *rest* positions) and then moved to where they stand now, as in the env.
The centre is where the members' facings meet (``facing_centre``, ``robust_facing_centre``), else it is measured
from positions (``group_circle``: as each groups model places members round it).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from ...core.humans import MAX_HUMANS, measured_group
from ...core.layouts import slot_keep
from ...core.range_memory import WALK_SPEED
from ...core.task import TaskParams
from ...params import RobotParams, SocialParams, _check
from ..camera import PinholeCamera
from ..detection.keypoint_range import BODY_MARGIN, EYES_TO_ANKLES_M
from ..tracking.tracker import Tracker, TrackerParams
from .facing_centre import facing_centre, robust_facing_centre

BODY_HEIGHT = 1.14  # m: the point of a person checked against the view (torso middle, urdf/human.urdf)

TORSO_HALF = (0.13, 0.23)  # m: half-depth (along the facing) and half-width of the torso box (urdf/human.urdf)
# the colour detector's ground error is ~0.05 m median (docs/benchmarks_tracking.md); people in a group stand or
# step slowly, so a lower acceleration noise than the street-tracking default keeps coasting tracks in place
TRACKER = TrackerParams(meas_std=0.1, birth_hits=2, accel_std=0.7)
# people ranged from keypoints (MoveNet): 0.1-0.6 m off where no laser ranges them (docs/tracking.md), so a
# detection's noise is larger, a conversing person's acceleration smaller (a range that jumps is not a step), a
# track needs three hits, and a detection within 0.4 m of a track (closer than people in a group stand) starts none.
# A range that jumps (the keypoints' 0.5-1 m too far, then the lasers') read as 1-2.7 m/s toward the robot, and
# tracks coasting on it, or taking a neighbour's detection 1.7 m away, stopped 10 of 20 `mixed` runs for a person
# "too close" (lockstep, virtual Pepper's bodies): a conversing person steps at most 0.5 m/s here (ours; the
# simulator's members at most SocialParams.max_speed 1.0, while the robot joins), nobody is 1 m from where they
# were predicted, and a track not detected stands (as remembered members do, ``GroupTracker.hold``)
TRACKER_KEYPOINTS = TrackerParams(meas_std=0.25, birth_hits=3, accel_std=0.3, min_new_dist=0.4, max_jump=1.0,
                                  max_speed=0.5, coast=False)
TORSO_HEIGHT = 0.60  # m: the proxy's torso box (urdf/human.urdf)
MIN_VISIBLE = 0.35  # share of a torso's width that must show inside the image for a cut box to count

@dataclasses.dataclass(frozen=True)
class GroupParams:
    """How long people are remembered and when they count as visible (ours)."""

    forget_frames: int = 5  # frames a remembered member's place is in clear view with nobody there
    same_person_m: float = 0.6  # a new track this close to a remembered member replaces it
    took_over_m: float = 0.3  # a track this close to where a member in the image stood took over its place
    max_range_m: float = 6.0  # people farther away are not expected to be detected
    person_halfwidth_m: float = 0.3  # a person's half-width across the line of sight: the torso's 0.23 m
    #   (urdf/human.urdf) plus 0.07 m for the estimate's error. Hides what lies behind it, and a person is
    #   expected to be detected only when both sides project inside the image (``perceive`` drops boxes cut by
    #   the image's side: close to the group, a member 20 deg off the axis is cut and goes undetected)
    edge_margin_m: float = 0.0  # m a person's side must also clear the image's side to be expected detected: what
    #   ``perceive`` asks of a box before it keeps it (MoveNet's: ``BODY_MARGIN`` of the body's height, 0.1 m)
    facing_turn_std: float = 0.3  # rad/s: how fast a conversing person's facing may change (the facing filter's
    #   process noise; people in a group turn their body slowly, their head faster: ours)
    facing_gate_deg: float = 180.0  # deg: a measured facing further than this from the filtered one is left out ...
    facing_switch: int = 3  # ... unless this many in a row are: then the filter restarts from the newest (it held
    #   a flipped facing, or the person turned)

    def __post_init__(self) -> None:
        for name, ok, expected in [(n, lambda v: type(v) is int and v >= 1, "an integer >= 1")
                                   for n in ("forget_frames", "facing_switch")] + [
                (n, lambda v: isinstance(v, int | float) and 0 < v < math.inf, "metres > 0")
                for n in ("same_person_m", "took_over_m", "max_range_m", "person_halfwidth_m")] + [
                (n, lambda v: isinstance(v, int | float) and 0 <= v < math.inf, "a number >= 0")
                for n in ("edge_margin_m", "facing_turn_std")] + [
                ("facing_gate_deg", lambda v: isinstance(v, int | float) and 0 < v <= 180, "degrees in (0, 180]")]:
            _check(ok(getattr(self, name)), "group", name, getattr(self, name), expected)


# the group memory for MoveNet's people: a person is expected detected only where perceive keeps their box
# (``deploy.perceive.whole_people``: ``BODY_MARGIN`` of the body's height clear of the image's side, 0.1 m)
# and a facing turned back left out (ours: MoveNet's keypoints turn 9-14 % of views by 180 deg, docs/
# benchmarks_movenet.md; taken in, one pulled the facing 90 deg aside and the centre with it. Through the observation
# model the shipped policy joined 70.0 % of `mixed` so, 78.5 % with this gate, 81.5 % without flips. 60 deg: 5-6
# sigma of MoveNet's facing noise; the colour chain turns none, and keeps every facing)
KEYPOINT_GROUP = GroupParams(edge_margin_m=BODY_MARGIN * EYES_TO_ANKLES_M, facing_gate_deg=60.0)


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
    rest: np.ndarray | None = None  # where the member stood while the robot was not joining (odometry frame)
    facing: float | None = None  # the direction the person faces (rad, odometry frame), where the detector tells
    facing_std: float = math.inf  # its standard deviation (rad)
    facing_outliers: int = 0  # measured facings in a row the filter left out (``GroupParams.facing_gate_deg``)
    born: int = 0  # the frame (``GroupTracker``'s count) this member was first reported
    last_seen: int = 0  # the last frame it was detected
    unseen_s: float = 0.0  # s it has been remembered (held by ``GroupTracker.hold``): 0 while detected, or while
    #   the tracker still coasts it (its own model moves it and widens its covariance)

    @property
    def reach(self) -> float:
        """How far (m) the person may have walked since the tracker lost them (``WALK_SPEED``)."""
        return WALK_SPEED * self.unseen_s


def group_circle(members: np.ndarray, robot_xy: np.ndarray, social: SocialParams, paper: bool = False
                 ) -> tuple[np.ndarray, float]:
    """Conversation centre (2,) and o-space radius (m) of members (n >= 2, (n, 2)): a pair's midpoint (real pairs
    stand symmetric about their centre), in the paper's model a point on the robot's side of the chord at the
    model's radius (``SocialParams.ospace_radius_for``); three or more their centroid (that of real groups), in the
    paper's model a least-squares circle through them."""
    pts = np.asarray(members, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n < 2:
        raise ValueError(f"group_circle: {n} member(s); need 2 or more")
    if n == 2:
        mid, half = 0.5 * (pts[0] + pts[1]), 0.5 * float(np.hypot(*(pts[1] - pts[0])))
        r = social.ospace_radius_for(2)
        if not paper or half >= r or half < 1e-6:
            return mid, max(half, 1e-6)
        normal = np.array([pts[0, 1] - pts[1, 1], pts[1, 0] - pts[0, 0]]) / (2.0 * half)
        if normal @ (robot_xy - mid) < 0:
            normal = -normal
        return mid + math.sqrt(r * r - half * half) * normal, r
    mean = pts.mean(axis=0)
    centroid = (mean, float(np.hypot(*(pts - mean).T).mean()))
    if not paper:  # real groups: the centre is the centroid (``layouts.real_layout``)
        return centroid
    # the paper's members stand on a circle: algebraic (Kasa) circle fit x^2 + y^2 + D x + E y + F = 0
    a = np.column_stack([pts, np.ones(n)])
    b = -(pts ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = -0.5 * sol[:2]
    r2 = float(centre @ centre - sol[2])
    if not (r2 > 0 and math.sqrt(r2) <= 3.0 * social.ospace_radius_for(n + 1)):  # collinear: fall back
        return centroid
    return centre, math.sqrt(r2)


def member_arrays(members: list[Member]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, 2), rest positions (n, 2), facings (n,; NaN unknown) and their std (n,) of tracked members,
    as ``GroupModel.update`` takes them."""
    pos = np.array([m.pos for m in members], dtype=float).reshape(-1, 2)
    rest = np.array([m.pos if m.rest is None else m.rest for m in members], dtype=float).reshape(-1, 2)
    facing = np.array([np.nan if m.facing is None else m.facing for m in members], dtype=float)
    std = np.array([m.facing_std for m in members], dtype=float)
    return pos, rest, facing, std


class GroupModel:
    """The group the policy sees: centre, o-space radius, joining weight and free slot, by the env's model.

    In the env a group is spawned at rest (its o-space radius, the rings its members keep, the distance at which a
    robot joins) and then moves; a joining robot widens its ring, and in the paper's model moves its centre toward
    the robot at once while the members follow over seconds. So the centre before joining (``centre0``) is
    measured from the members while the robot is outside the joining zone (smoothed over frames) and held while
    it is inside (a calibrated pair's is its midpoint throughout); the group is spawned
    at the members' rest positions (``Member.rest``) and its members put where they stand now; the free slot is
    the env's (``Group.free_slot``). ``keep`` and ``paper`` are the training env's (``layouts.slot_keep``; the
    groups model).
    """

    def __init__(self, social: SocialParams, keep: float, paper: bool = False, smoothing: float = 0.3,
                 robust: bool = False) -> None:
        self.social, self.keep, self.paper, self.smoothing = social, keep, paper, smoothing
        self.robust = robust  # three or more members: ``robust_facing_centre`` (facings that may be far off)
        self.centre0: np.ndarray | None = None
        self.n = 0
        self.weight = 0.0  # the joining weight of the last update (read by ``GroupTracker`` to record rests)
        self.centre: np.ndarray | None = None  # the centre the last group was spawned around (before joining)

    def reset(self) -> None:
        self.centre0, self.n, self.weight, self.centre = None, 0, 0.0, None

    def group(self, members: np.ndarray, centre: np.ndarray, rest: np.ndarray | None = None) -> Any:
        """The env's group spawned where ``rest`` (default ``members``) stand around ``centre``
        (``humans.measured_group``), its members then put at ``members``; the ``MAX_HUMANS`` nearest the centre
        when more people are tracked, as the observation holds no more."""
        members = np.asarray(members, dtype=float).reshape(-1, 2)
        rest = members if rest is None else np.asarray(rest, dtype=float).reshape(-1, 2)
        if len(members) > MAX_HUMANS:
            keep = np.argsort(np.hypot(*(members - centre).T), kind="stable")[:MAX_HUMANS]
            members, rest = members[keep], rest[keep]
        g = measured_group(self.social, rest, centre, self.keep, self.paper)
        g.pos[:] = members
        return g

    def update(self, members: np.ndarray, robot_xy: np.ndarray, rest: np.ndarray | None = None,
               facing: np.ndarray | None = None, facing_std: np.ndarray | None = None
               ) -> tuple[np.ndarray, float, float, np.ndarray]:
        """Centre (2,), o-space radius (m), joining weight and free slot (2,) for members (n >= 2, (n, 2)) and
        the robot; ``rest``: where each member stood before the robot came to join (default: where it stands);
        ``facing``/``facing_std`` (n,): where each faces (rad, NaN unknown): where their rays meet is the centre
        (``facing_centre``), else it is measured from positions (``group_circle``)."""
        members = np.asarray(members, dtype=float).reshape(-1, 2)
        rest = members if rest is None else np.asarray(rest, dtype=float).reshape(-1, 2)
        n = len(members)
        if facing is None:
            met = None
        elif self.robust and n >= 3:
            met = robust_facing_centre(members, facing, facing_std)
        else:
            met = facing_centre(members, facing, facing_std, self.social.ospace_radius_for(max(n, 2)))
        measured = met if met is not None else group_circle(members, robot_xy, self.social, self.paper)[0]
        if self.centre0 is None or n != self.n:
            self.centre0, self.n = measured, n
        else:
            probe = self.group(members, measured)
            probe.update_centre(robot_xy)
            if probe.join_weight == 0.0:  # not joining: measure centre0
                self.centre0 = self.centre0 + self.smoothing * (measured - self.centre0)
        # a calibrated pair stands symmetric about its centre, in the env as it re-forms too: its midpoint, now (a
        # held centre would make one of its gaps wider than the other as the estimates jitter; the env breaks their
        # 10 deg tie toward the robot). The paper's pair moves its centre toward the robot: the held one, shifted.
        centre = members.mean(axis=0) if n == 2 and not self.paper and met is None else self.centre0
        self.centre = centre
        g = self.group(members, centre, rest)
        g.update_centre(robot_xy)
        self.weight = g.join_weight
        return g.centre.copy(), g.radius, g.join_weight, g.free_slot(robot_xy)


def default_model(social: SocialParams) -> GroupModel:
    """``GroupModel`` with the robot's place as the default robot and task keep it (``layouts.slot_keep``)."""
    task = TaskParams()
    return GroupModel(social, slot_keep(social, RobotParams().reach, task.intimate_zone, task.route_margin))


def _se2(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([[c, -s], [s, c]]), np.asarray(pose[:2], dtype=float)


class GroupTracker:
    """The Kalman tracker (ego-motion compensated) plus the memory of people out of view."""

    def __init__(self, camera: PinholeCamera, tracker: TrackerParams | None = None,
                 params: GroupParams | None = None, social: SocialParams | None = None,
                 model: GroupModel | None = None) -> None:
        """``model``: the loop's group model, whose joining weight tells when members stand at rest (default: the
        env's defaults)."""
        self.camera = camera
        self.tracker = Tracker(tracker)
        self.p = params or GroupParams()
        self.social = social or SocialParams()
        self.model = model or default_model(self.social)
        self.members: dict[int, Member] = {}
        self.alias: dict[int, int] = {}  # tracker id -> member id, for tracks that took over a member
        self._known: set[int] = set()  # tracker ids reported before
        self.frames = 0  # frames seen so far (``Member.born``, ``Member.last_seen``)

    def visible(self, xy_robot: np.ndarray, seen_robot: np.ndarray) -> np.ndarray:
        """Which robot-frame points (k, 2) a detector should find: in range, the whole body inside the image
        (``person_halfwidth_m`` either side), and not hidden behind a nearer seen person (``seen_robot``, (m, 2))."""
        xy = np.asarray(xy_robot, dtype=float).reshape(-1, 2)
        rng = np.hypot(xy[:, 0], xy[:, 1])
        across = np.column_stack([-xy[:, 1], xy[:, 0]]) / np.maximum(rng, 1e-6)[:, None]  # unit, across the sight line
        edge = across * (self.p.person_halfwidth_m + self.p.edge_margin_m)
        ok = (rng <= self.p.max_range_m) & (xy[:, 0] > 0)
        for side in (xy - edge, xy + edge):  # both sides of the body inside the image, as perceive keeps boxes
            u = self.camera.robot_to_pixel(np.column_stack([side, np.full(len(xy), BODY_HEIGHT)]))[:, 0]
            ok &= np.isfinite(u) & (u > 1) & (u < self.camera.width - 1) & (side[:, 0] > 0)
        if len(seen_robot):
            bearing, s_bearing = np.arctan2(xy[:, 1], xy[:, 0]), np.arctan2(seen_robot[:, 1], seen_robot[:, 0])
            s_rng = np.hypot(seen_robot[:, 0], seen_robot[:, 1])
            width = np.arctan2(self.p.person_halfwidth_m, np.maximum(rng, 1e-3))[:, None] + np.arctan2(
                self.p.person_halfwidth_m, np.maximum(s_rng, 1e-3))[None, :]
            gap = np.abs(np.remainder(bearing[:, None] - s_bearing[None, :] + math.pi, 2 * math.pi) - math.pi)
            hidden = ((s_rng[None, :] < rng[:, None] - 0.2) & (gap < width)).any(axis=1)
            ok &= ~hidden
        return ok

    @staticmethod
    def hold(gone: list[Member], dt: float = 0.0) -> None:
        """Members out of view stay where they were last estimated, standing, their uncertainty growing at walking
        speed over this frame's ``dt`` s (``Member.reach``; the covariance by its square). Measured against the virtual
        Pepper's ground truth (20 `mixed` lockstep runs, 4,618 member-ticks out of view): median error 0.13 m, p90
        0.30 m; moved by the social force model around the group (Luber et al., ICRA 2010, spawned at their rest
        positions as in the env) 0.21 / 0.50 m; coasting on their last velocity 0.23 / 0.44 m. Conversing people
        barely move, and a model fed estimated rests and velocities drifts: on five-member groups that drift
        turned the widest gap, and the free slot with it. Tracks the tracker still coasts (a few frames) move on
        by its constant-velocity model: held as well, a member making room out of view was not followed and 1 of
        20 runs entered the intimate zone (16/20 joined against 19/20). Keypoint tracks, whose velocity a range
        that jumps makes up, stand instead (``TRACKER_KEYPOINTS``)."""
        for m in gone:
            m.vel = np.zeros(2)
            before = m.reach
            m.unseen_s += dt
            m.cov = m.cov + (m.reach ** 2 - before ** 2) * np.eye(2)

    def _take_over(self, states: list[Any], rot: np.ndarray, t: np.ndarray) -> list[Any]:
        """A track reported for the first time, detected now, within ``same_person_m`` of a member not detected
        now (a remembered member, or a coasting track) is that member seen again: it takes the member's id (and
        rest), and a coasting track it replaces is deleted. Without this a person who left the view (or was hidden
        long enough for the tracker to drop them) came back under a new id, and a track born beside a coasting one
        showed one person twice."""
        alive = {tr.id for tr in self.tracker.tracks}  # ids never come back: forget those the tracker deleted
        self._known &= alive
        self.alias = {k: v for k, v in self.alias.items() if k in alive}
        new = [st for st in states if st.id not in self._known and st.misses == 0]
        self._known.update(st.id for st in states)
        if not new:
            return states
        coasting = {self.alias.get(st.id, st.id): st for st in states if st.misses > 0}
        reported = {self.alias.get(st.id, st.id) for st in states}
        old = {k: m.pos for k, m in self.members.items() if k not in reported}
        old.update({k: rot @ st.position + t for k, st in coasting.items()})
        if not old:
            return states
        keys = list(old)
        d = np.hypot(*(np.array([rot @ st.position + t for st in new])[:, None, :]
                       - np.array([old[k] for k in keys])[None, :, :]).transpose(2, 0, 1))
        rows, cols = linear_sum_assignment(np.where(d < self.p.same_person_m, d, 1e9))
        dropped = set()
        for r, c in zip(rows, cols, strict=True):
            if d[r, c] < self.p.same_person_m:
                self.alias[new[r].id] = keys[c]
                if keys[c] in coasting:
                    dropped.add(coasting[keys[c]].id)
        if dropped:  # the coasting tracks taken over: gone from the tracker too
            self.tracker.tracks = [tr for tr in self.tracker.tracks if tr.id not in dropped]
            for tid in dropped:
                self.alias.pop(tid, None)
        return [st for st in states if st.id not in dropped]

    def _filter_facing(self, m: Member, measured: tuple[float, float] | None, dt: float) -> None:
        """A one-state Kalman filter on the member's facing angle: the facing drifts (``facing_turn_std``), a
        measurement (angle, std) pulls it by its share of the variance; one further than ``facing_gate_deg`` off is
        left out, unless ``facing_switch`` in a row are (then the filter starts again from it)."""
        if m.facing is not None:
            m.facing_std = math.hypot(m.facing_std, self.p.facing_turn_std * math.sqrt(dt))
        if measured is None:
            return
        z, r = measured
        if m.facing is None or not math.isfinite(m.facing_std):
            m.facing, m.facing_std = math.remainder(z, 2 * math.pi), r
            return
        if abs(math.remainder(z - m.facing, 2 * math.pi)) > math.radians(self.p.facing_gate_deg):
            m.facing_outliers += 1
            if m.facing_outliers >= self.p.facing_switch:
                m.facing, m.facing_std, m.facing_outliers = math.remainder(z, 2 * math.pi), r, 0
            return
        m.facing_outliers = 0
        var, rr = m.facing_std ** 2, r * r
        k = var / (var + rr)
        m.facing = math.remainder(m.facing + k * math.remainder(z - m.facing, 2 * math.pi), 2 * math.pi)
        m.facing_std = math.sqrt((1.0 - k) * var)

    def update(self, detections: np.ndarray, dt: float, pose: np.ndarray, facing: np.ndarray | None = None,
               facing_std: np.ndarray | None = None) -> list[Member]:
        """One frame's robot-frame ground detections (n, 2) taken at odometry ``pose``; returns the members.
        ``facing``/``facing_std`` (n,): each detected person's facing relative to their line of sight (rad, 0:
        looking at the robot, counter-clockwise positive; NaN unknown), filtered per member (``Member.facing``)."""
        xy = np.asarray(detections, dtype=float).reshape(-1, 2)
        payloads = None
        if facing is not None:  # odometry-frame facing: the direction person -> camera, turned by phi
            toward = np.arctan2(-xy[:, 1], -xy[:, 0]) + float(pose[2])
            std = np.full(len(xy), math.inf) if facing_std is None else np.asarray(facing_std, dtype=float)
            payloads = [(float(toward[k] + f), float(sd)) if np.isfinite(f) and np.isfinite(sd) else None
                        for k, (f, sd) in enumerate(zip(np.asarray(facing, dtype=float), std, strict=True))]
        self.frames += 1
        states = self.tracker.update(xy, dt=dt, odom=pose, payloads=payloads)
        rot, t = _se2(pose)
        states = self._take_over(states, rot, t)
        seen = {}
        at_rest = self.model.weight == 0.0  # the robot is not joining: where people stand now is their rest
        for st in states:
            mid = self.alias.get(st.id, st.id)
            m = Member(mid, rot @ st.position + t, rot @ st.velocity, rot @ st.covariance[:2, :2] @ rot.T,
                       st.misses == 0)
            old = self.members.get(mid)
            m.rest = m.pos.copy() if at_rest or old is None or old.rest is None else old.rest
            m.born = self.frames if old is None else old.born
            m.last_seen = self.frames if m.seen or old is None else old.last_seen
            if old is not None:
                m.facing, m.facing_std, m.facing_outliers = old.facing, old.facing_std, old.facing_outliers
            self._filter_facing(m, st.payload if st.misses == 0 else None, dt)
            seen[mid] = m
        seen_robot = np.array([st.position for st in states]).reshape(-1, 2)
        gone = [m for k, m in self.members.items() if k not in seen]
        for m in gone:
            m.seen = False
        self.hold(gone, dt)
        if gone:
            local = (np.array([m.pos for m in gone]) - t) @ rot  # odometry -> robot frame
            # anyone known may hide a remembered member: a person cut by the image's side is not detected (perceive
            # drops the box) yet hides whoever stands behind them, who was then forgotten and came back under a new id
            in_view = self.visible(local, np.vstack([seen_robot, local]))
            in_image = self.visible(local, np.zeros((0, 2)))
            for m, vis, shown in zip(gone, in_view, in_image, strict=True):
                m.unseen_in_view = m.unseen_in_view + 1 if vis else 0
                # someone reported since m was last detected, within same_person_m, is m again; someone reported
                # while m was still detected is a neighbour (5 members stand 0.45-0.5 m apart: deleting m dropped a
                # member, its gap joining the next, 5 times in one lockstep run), unless m is in the image and they
                # stand where m was (``took_over_m``: an id that jumped across onto m's place)
                d = np.array([float(np.hypot(*(o.pos - m.pos))) for o in seen.values()])
                young = np.array([o.born > m.last_seen for o in seen.values()], dtype=bool)
                dup = bool(len(d)) and bool(((d < self.p.same_person_m) & young).any()
                                            or (shown and (d < self.p.took_over_m).any()))
                if dup or m.unseen_in_view >= self.p.forget_frames:
                    del self.members[m.id]
        self.members.update(seen)
        return list(self.members.values())
