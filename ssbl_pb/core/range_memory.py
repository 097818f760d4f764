"""What the base's lasers saw lately and can no longer see: ``RangeMemory`` remembers unexplained range returns
and tells where whoever they came from could stand unseen now (the lasers leave blind sectors 30-70 deg either side
and behind, ``range_sensors``). Deploy's guards brake for these places (``deploy.guards.Guards``), and so does the
training env's model of them (``env.engine.batched.BatchedApproach._range_guard``)."""

from __future__ import annotations

import functools
import math

import numpy as np

from .range_sensors import RANGES, lasers_see_body

# m/s a person out of view may walk: how fast a remembered member's uncertainty grows (``Member.reach``). Comfortable
# walking is 1.27-1.46 m/s (Bohannon 1997, adults 20-79); ETH/UCY pedestrians moving faster than 0.3 m/s walk at a
# median 1.16 m/s, quartiles 0.78-1.45 (shared/data/trajectories, ``calib.humans``); someone in a conversation
# who moves steps rather than walks, and the simulated members never exceed SocialParams.max_speed (1.0)
WALK_SPEED = 1.0
# s an unexplained range return is remembered (``RangeMemory``). Ours: braking for where they could be slows the
# robot, so it reaches someone standing in a blind sector later: over qi, the stranger fault's person about 6 s
# after the lasers last saw them; remembered for 4 s, the robot then drove on to 0.46 m from them (0.67 m with 10 s)
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
    `mixed` lockstep runs). A seen-free place needs no memory: whoever is there now shows in the scan."""

    def __init__(self, human_radius: float) -> None:
        self.r = human_radius
        self.points = np.zeros((0, 2))  # odometry frame (m), one per ``MEMORY_CELL``
        self.times = np.zeros(0)  # when each was last seen (s, the loop's clock)
        self.hidden, self.bins = _hidden_centres(float(human_radius))

    def clear(self) -> None:
        """Forget every return (a new episode)."""
        self.points, self.times = np.zeros((0, 2)), np.zeros(0)

    def update(self, points: np.ndarray, near: np.ndarray, now: float, people: np.ndarray) -> None:
        """Remember the returns at odometry-frame ``points`` where ``near`` (those the map does not explain, within
        ``MEMORY_REACH``) that no tracked person at odometry ``people`` explains; forget those older than
        ``RANGE_MEMORY_S`` or explained by a person now."""
        fresh = np.asarray(points, dtype=float).reshape(-1, 2)[np.asarray(near, dtype=bool)]
        people = np.asarray(people, dtype=float).reshape(-1, 2)
        keep = now - self.times <= RANGE_MEMORY_S
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
        """Where someone last seen at a remembered return (before ``now``) could stand unseen: of the hidden body
        centres within ``WALK_SPEED`` times its age (at most ``PHANTOM_REACH``) of the body it came from, the
        nearest the robot in each 3 deg of bearing (robot frame (k, 2)); none where the lasers would see every place
        they could be."""
        old = (self.times < now - 1e-9) & (now - self.times <= RANGE_MEMORY_S)
        if not old.any():
            return np.zeros((0, 2))
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = self.points[old] - np.asarray(pose[:2], dtype=float)
        local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])  # robot frame
        reach = np.minimum(WALK_SPEED * (now - self.times[old]), PHANTOM_REACH) + self.r
        near = (np.hypot(*(self.hidden[None] - local[:, None]).transpose(2, 0, 1)) <= reach[:, None]).any(axis=0)
        if not near.any():
            return np.zeros((0, 2))
        pts, bins = self.hidden[near], self.bins[near]
        order = np.lexsort((np.hypot(*pts.T), bins))  # by bearing, nearest first
        first = np.r_[True, bins[order][1:] != bins[order][:-1]]
        return pts[order][first]
