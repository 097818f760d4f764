"""What the base's lasers saw lately and can no longer see: ``RangeMemory`` remembers unexplained range returns
and tells where whoever they came from could stand unseen now (the lasers leave blind sectors 30-70 deg either side
and behind, ``range_sensors``). Deploy's guards brake for these places (``deploy.guards.Guards``), and so does the
training env's model of them (``env.engine.batched.BatchedApproach._range_guard``)."""

from __future__ import annotations

import functools
import math

import numpy as np

from .range_sensors import RANGES, in_laser_fields, lasers_see_body

# m/s a person out of view may walk: how fast a remembered member's uncertainty grows (``Member.reach``). Comfortable
# walking is 1.27-1.46 m/s (Bohannon 1997, adults 20-79); ETH/UCY pedestrians moving faster than 0.3 m/s walk at a
# median 1.16 m/s, quartiles 0.78-1.45 (shared/data/trajectories, ``calib.humans``); someone in a conversation
# who moves steps rather than walks, and the simulated members never exceed SocialParams.max_speed (1.0)
WALK_SPEED = 1.0
# s an unexplained range return is remembered as someone who may walk anywhere unseen (``RangeMemory``). Ours: braking
# for where they could be slows the robot, so it reaches someone standing in a blind sector later: over qi, the
# stranger fault's person about 6 s after the lasers last saw them; remembered for 4 s, the robot then drove on to 0.46
# m from them (0.67 m with 10 s). Past it, the return stays where it was until the lasers see that place empty: a
# member standing beside the robot, in a blind sector, was forgotten after 10 s and the robot drove 0.16 m into them
# (lockstep `mixed`, seeds 500010 and 500013: 0.43 and 0.42 m, inside the 0.45 m intimate zone)
RANGE_MEMORY_S = 10.0
# m the place where someone could stand unseen grows to (at ``WALK_SPEED``, in 1.25 s: the robot needs 1.2 s to
# brake from full speed at Pepper's 0.3 m/s^2). Ours: the stranger fault's person walked up to 1.4 m after the
# lasers last saw them (lockstep, seed 30: with 1.0 m they stood beyond every phantom and the robot came 0.24 m
# from them; 1.25 m plus their body's radius covers it). 1.5 m, without a map (walls remembered too), kept the
# shipped policy from its place; grown for the memory's 10 s, it would reach every blind direction round the robot
PHANTOM_REACH = 1.25
MEMORY_CELL = 0.2  # m: the newest remembered return per cell of this size (a leg's returns share one or two)
MEMORY_REACH = 3.0  # m from the robot's centre beyond which returns are not remembered (the lasers' range)
PERSON_REACH = 0.6  # m from a tracked person within which a return is theirs (their body's 0.28 m and the remembered
#   estimate's p90 error, 0.30 m, ``GroupTracker.hold``): not remembered, the member guard has them


SEEN_PAST = 0.1  # m: a laser return farther away whose line from the robot passes this close to a remembered return
#   shows its place empty (Pepper's 4 deg laser segments leave gaps: a member's edge seen once, then between two
#   segments, was taken for seen by the lasers' fields and forgotten; ours)


def seen_past(points: np.ndarray, returns: np.ndarray) -> np.ndarray:
    """Which robot-frame ``points`` (k, 2) a laser return now (robot frame ``returns`` (m, 2)) lies beyond, on a line
    from the robot's centre passing within ``SEEN_PAST`` of the point."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    q = np.asarray(returns, dtype=float).reshape(-1, 2)
    if not len(p) or not len(q):
        return np.zeros(len(p), dtype=bool)
    dq = np.hypot(q[:, 0], q[:, 1])
    u = q / np.maximum(dq, 1e-9)[:, None]
    along = p @ u.T  # (k, m): each point's distance along each return's line
    across = np.abs(p[:, None, 0] * u[None, :, 1] - p[:, None, 1] * u[None, :, 0])
    return ((across < SEEN_PAST) & (along > 0) & (dq[None] > along + SEEN_PAST)).any(axis=1)


EDGE_DIRECTIONS = np.radians(np.arange(-90.0, 91.0, 15.0))  # where a body's middle may lie behind a return on its
#   edge: round the far half of the body, from the line of sight (ours, 15 deg: 0.07 m apart on a 0.28 m body)


def edge_bodies(returns: np.ndarray, radius: float) -> np.ndarray:
    """Body centres (robot frame) behind robot-frame laser ``returns`` (k, 2) on their surface that no laser's field
    holds: a laser sees the edge of such a body, and its middle, out of view, is where the robot may run into it. A
    member at 40 deg to the right, 1.04 m away, showed the front laser only its edge at 27 deg, tick after tick; the
    guard braked for that point and the robot drove 0.16 m into the member's intimate zone (lockstep `mixed`, seed
    500013)."""
    p = np.asarray(returns, dtype=float).reshape(-1, 2)
    if not len(p):
        return np.zeros((0, 2))
    ray = np.arctan2(p[:, 1], p[:, 0])[:, None] + EDGE_DIRECTIONS[None]
    centres = (p[:, None] + radius * np.stack([np.cos(ray), np.sin(ray)], axis=-1)).reshape(-1, 2)
    return centres[~in_laser_fields(centres)]


@functools.lru_cache(maxsize=4)
def _hidden_centres(radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Body centres (robot frame) no laser would see any of: out of every field (centre and both sides), from just
    beyond the footprint to the lasers' range and a body beyond; and each one's bearing bin (3 deg)."""
    bearing, dist = np.meshgrid(np.radians(np.arange(-180, 180, 3.0)), np.arange(0.5, RANGES.laser_max + 0.3, 0.05))
    c = np.column_stack([(dist * np.cos(bearing)).ravel(), (dist * np.sin(bearing)).ravel()])
    hidden = ~lasers_see_body(c, radius)
    return c[hidden], np.indices(bearing.shape)[1].ravel()[hidden]


class RangeMemory:
    """Unexplained range returns (not on the map, not by a tracked person) remembered in the odometry frame for
    ``RANGE_MEMORY_S``, and where whoever they came from could be now (``phantoms``): someone a laser saw may since
    have walked (``WALK_SPEED``) into the lasers' blind sectors, 30-70 deg either side and behind, where no sensor
    sees them again (the shipped policy drives into those sectors most of the time: 61 % of its moving ticks in the
    `mixed` lockstep runs); after that, someone who stayed where a laser last saw them, until the lasers see that
    place empty. A seen-free place needs no memory: whoever is there now shows in the scan."""

    def __init__(self, human_radius: float, surface: bool = False) -> None:
        """``surface``: the points are laser returns on bodies' surfaces (deploy's), so a body a laser sees the edge
        of may stand with its middle out of every field (``edge_bodies``); else body centres (the training env's)."""
        self.r = human_radius
        self.surface = surface
        self.points = np.zeros((0, 2))  # odometry frame (m), one per ``MEMORY_CELL``
        self.times = np.zeros(0)  # when each was last seen (s, the loop's clock)
        self.hidden, self.bins = _hidden_centres(float(human_radius))

    def clear(self) -> None:
        """Forget every return (a new episode)."""
        self.points, self.times = np.zeros((0, 2)), np.zeros(0)

    def update(self, points: np.ndarray, near: np.ndarray, now: float, people: np.ndarray, pose: np.ndarray,
               beams: np.ndarray | None = None) -> None:
        """Remember the returns at odometry-frame ``points`` where ``near`` (those the map does not explain, within
        ``MEMORY_REACH``) that no tracked person at odometry ``people`` explains; forget those explained by a person
        now, and those older than ``RANGE_MEMORY_S`` whose place the lasers see empty from the robot at odometry
        ``pose``: a laser return now (odometry ``beams``) lies beyond it on a line through it (``seen_past``);
        without ``beams`` (the training env's bodies), where a laser would see a body there (``lasers_see_body``)."""
        fresh = np.asarray(points, dtype=float).reshape(-1, 2)[np.asarray(near, dtype=bool)]
        people = np.asarray(people, dtype=float).reshape(-1, 2)
        local = self._local(self.points, pose)
        free = lasers_see_body(local, self.r) if beams is None else seen_past(local, self._local(beams, pose))
        keep = (now - self.times <= RANGE_MEMORY_S) | ~free
        if len(people):  # a person tracked since (the lasers see members before the camera does) explains them too
            if len(fresh):
                fresh = fresh[np.hypot(*(fresh[:, None] - people[None]).transpose(2, 0, 1)).min(axis=1) > PERSON_REACH]
            if len(self.points):
                keep &= np.hypot(*(self.points[:, None] - people[None]).transpose(2, 0, 1)).min(axis=1) > PERSON_REACH
        cells = {}  # the newest per cell
        for p, t in zip(np.vstack([self.points[keep], fresh]).tolist(), [*self.times[keep], *[now] * len(fresh)],
                        strict=True):
            cells[(math.floor(p[0] / MEMORY_CELL), math.floor(p[1] / MEMORY_CELL))] = (p, t)
        self.points = np.array([v[0] for v in cells.values()]).reshape(-1, 2)
        self.times = np.array([v[1] for v in cells.values()], dtype=float)

    def phantoms(self, pose: np.ndarray, now: float) -> np.ndarray:
        """Where someone last seen at a remembered return (before ``now``) could stand unseen (robot frame (k, 2)):
        within ``RANGE_MEMORY_S``, of the hidden body centres within ``WALK_SPEED`` times its age (at most
        ``PHANTOM_REACH``) of the body it came from, the nearest the robot in each 3 deg of bearing, none where the
        lasers would see every place they could be; past it, the return itself (``update`` forgets it once the
        lasers see its place empty); with ``surface``, also the bodies out of every field a return may lie on the
        edge of (``edge_bodies``)."""
        age = now - self.times
        young, stayed = (age > 1e-9) & (age <= RANGE_MEMORY_S), age > RANGE_MEMORY_S  # stayed: kept while unseen
        if not (young.any() or stayed.any() or (self.surface and len(age))):
            return np.zeros((0, 2))
        local = self._local(self.points, pose)
        reach = np.minimum(WALK_SPEED * age[young], PHANTOM_REACH) + self.r
        near = (np.hypot(*(self.hidden[None] - local[young][:, None]).transpose(2, 0, 1)) <= reach[:, None]).any(axis=0)
        pts, bins = self.hidden[near], self.bins[near]
        order = np.lexsort((np.hypot(*pts.T), bins))  # by bearing, nearest first
        first = np.r_[True, bins[order][1:] != bins[order][:-1]] if len(order) else np.zeros(0, dtype=bool)
        edge = edge_bodies(local[age <= RANGE_MEMORY_S], self.r) if self.surface else np.zeros((0, 2))
        return np.vstack([pts[order][first], local[stayed], edge])

    @staticmethod
    def _local(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """Odometry-frame ``points`` (k, 2) in the frame of the robot at ``pose``."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = np.asarray(points, dtype=float).reshape(-1, 2) - np.asarray(pose[:2], dtype=float)
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
