"""Deploy's guards after the policy's shield, on the command the loop sends: people out of the camera's view
(``guard_unseen``: a remembered member may have walked since last detected) and the base's range returns
(``guard_ranges``: whatever Pepper's lasers and sonars hit, seen by the camera or not, and what they hit lately,
``RangeMemory``: the lasers leave blind sectors 30-70 deg either side and behind).

Both brake only the closing speed (``core.shield``'s rule, ``sqrt(2 a (c - c_min))``): motion past or away from
what they brake for is untouched, so they slow or stop the robot toward it and let it slide along.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.range_memory import MEMORY_REACH, WALK_SPEED, RangeMemory
from ..core.range_sensors import RETURN_MARGIN, in_laser_fields
from ..core.shield import CLEARANCE_FAR, PLACE_NEAR, ShieldParams, brake_closing, brake_returns, footprint_clearance
from ..env.rooms.obstacles import field_at
from .frames import Frames, inverse, transform_points
from .robot import RangeScan

# m: the most the clearance kept from a member out of view grows to (at ``WALK_SPEED``, in half a second). Ours:
# where deploy remembers a member is 0.13 m off at the median and 0.30 m at p90 (``GroupTracker.hold``), the social
# force model moved members 0.50 m at p90 while out of view, and the deploy benchmark's fault walks one 0.5 m toward
# the robot's path; beyond that the range sensors guard
UNSEEN_MARGIN = 0.5
# m from the estimated place within which that margin fades out (none within ``PLACE_NEAR``, all of it beyond
# ``CLEARANCE_FAR``, linear between): near the place the neighbours are out of view by design and the shield keeps
# the place's clearance (``ShieldParams.from_env``, within ``CLEARANCE_NEAR``-``CLEARANCE_FAR``). Faded out only
# within 0.6 m, 0.5 m would bar the way in between two neighbours: 1.2 m from the place, 100 deg apart from the
# robot's way in, they are under 1.05 m from a robot 0.8 m out (by hand)
UNSEEN_NEAR, UNSEEN_FAR = PLACE_NEAR, CLEARANCE_FAR
MAPPED = 0.15  # m: a return this close to the map's walls or obstacles is theirs (the map's cells are 0.05 m,
#   localisation drifts by a few centimetres: ours)


def unseen_margin(reach: np.ndarray, slot_distance: float = math.inf) -> np.ndarray:
    """The clearance (m) deploy adds for each member from how far they may have walked since last detected
    (``reach``, m; ``estimate.Member.reach``), capped at ``UNSEEN_MARGIN`` and faded out near the place."""
    far = min(max((slot_distance - UNSEEN_NEAR) / (UNSEEN_FAR - UNSEEN_NEAR), 0.0), 1.0)
    return np.minimum(np.asarray(reach, dtype=float), UNSEEN_MARGIN) * far


def guard_unseen(cmd: np.ndarray, pos: np.ndarray, margin: np.ndarray, pose: np.ndarray, clearance: float,
                 shield: ShieldParams) -> np.ndarray:
    """``cmd`` (forward, left, turn) with its closing speed on each member at odometry-frame ``pos`` (k, 2) braked
    for ``clearance`` plus that member's ``margin`` (k,; 0: left to the policy's shield), from the robot at
    odometry ``pose``."""
    keep = np.asarray(margin) > 0
    if not keep.any():
        return cmd
    c, sn = math.cos(pose[2]), math.sin(pose[2])
    local = (pos[keep] - pose[:2]) @ np.array([[c, -sn], [sn, c]])  # odometry -> robot frame
    out = np.array(cmd, dtype=float)
    out[:2] = brake_closing(out[:2], local, clearance + np.asarray(margin)[keep], shield)
    return out


def mapped(frames: Frames, points: np.ndarray) -> np.ndarray:
    """Which odometry-frame points (k, 2) lie within ``MAPPED`` of the map's walls or obstacles (none without a
    map)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    room = frames.room
    if room is None or frames.room_from_odom is None:
        return np.zeros(len(pts), dtype=bool)
    xy = frames.room_points(pts)
    sx, sy = room.room_size
    wall = np.minimum(sx / 2 - np.abs(xy[:, 0]), sy / 2 - np.abs(xy[:, 1]))
    known = wall < MAPPED
    obstacles = room.obstacles
    if obstacles is not None:
        known |= np.array([field_at(obstacles.field, obstacles.x0, obstacles.y0, float(x), float(y)) < MAPPED
                           for x, y in xy.tolist()], dtype=bool)
    return known


def guard_ranges(cmd: np.ndarray, points: np.ndarray, known: np.ndarray, clearance: float, shield: ShieldParams
                 ) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``cmd`` (forward, left, turn) braked for the range returns at robot-frame ``points`` (k, 2)
    (``shield.brake_returns``): for ``clearance`` (people's: a laser sees a person's legs, within the 0.28 m body
    circle the intimate zone is measured to), or for the shield's ``obstacle_clearance_min`` where ``known`` (k,)
    says the map explains the return (walls and furniture: the policy was trained to pass those at that); and what
    it changed for the log (None where nothing): the command before and after, the nearest return (robot frame) and
    its clearance from the footprint's circle."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(pts):
        return cmd, None
    c_min = np.where(np.asarray(known, dtype=bool), shield.obstacle_clearance_min, clearance)
    out = np.array(cmd, dtype=float)
    out[:2] = brake_returns(out[:2], pts, c_min, shield)
    if np.allclose(out, cmd, atol=1e-9):
        return out, None
    clear = footprint_clearance(pts, 0.0, shield, radius=0.0)[0]
    k = int(np.argmin(clear))
    return out, {"before": list(map(float, cmd)), "after": out.tolist(), "nearest": pts[k].tolist(),
                 "clearance_m": float(clear[k]), "returns": len(pts)}


class Guards:
    """Both guards as the loop applies them after the policy's shield: ``guard_unseen`` for remembered members
    beyond the shield's ``clearance`` (with range sensors, only those outside the lasers' fields, which see the
    others), then ``guard_ranges`` for the returns now and remembered (``RangeMemory``), for ``stop_distance`` plus
    ``RETURN_MARGIN``; ``frames`` tells which returns the map explains."""

    def __init__(self, shield: ShieldParams, clearance: float, stop_distance: float, frames: Frames) -> None:
        self.shield, self.clearance, self.stop_distance, self.frames = shield, clearance, stop_distance, frames
        self.memory = RangeMemory(shield.human_radius, surface=True)

    def __call__(self, cmd: np.ndarray, scan: RangeScan | None, members: list[Any], pos: np.ndarray,
                 pose: np.ndarray, age: float | None, now: float, slot_distance: float = math.inf,
                 scan_pose: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """``cmd`` guarded, and the log's columns: ``unseen_guard`` and ``range_guard`` (what each changed, or
        None), ``ranges`` (how many returns now; None without range sensors). ``members`` (``estimate.Member``) at
        odometry-frame ``pos`` from an estimate ``age`` s old; the robot at odometry ``pose`` now, at ``scan_pose``
        when ``scan`` was measured (default: ``pose``; its returns are moved by the difference: turning at 0.5
        rad/s, a laser frame's age smeared a wall's returns 0.2 m off the map)."""
        reach = np.array([m.reach + WALK_SPEED * (age or 0.0) if m.reach > 0 else 0.0 for m in members])
        if scan is not None and len(pos):
            reach[in_laser_fields(transform_points(inverse(pose), pos))] = 0.0
        out = guard_unseen(cmd, pos, unseen_margin(reach, slot_distance), pose, self.clearance, self.shield)
        cols = {"unseen_guard": None if np.allclose(out, cmd, atol=1e-9) else {"before": cmd, "after": out},
                "ranges": None, "range_guard": None}
        if scan is None:
            return out, cols
        odom = transform_points(pose if scan_pose is None else scan_pose, scan.points)
        local = transform_points(inverse(pose), odom)
        known = mapped(self.frames, odom)
        lasers = np.arange(len(odom)) < len(odom) - scan.sonars  # a sonar's echo is no place to remember
        self.memory.update(odom, lasers & ~known & (np.hypot(*scan.points.T) <= MEMORY_REACH), now, pos, pose,
                           odom[lasers])
        before, clearance = out.copy(), self.stop_distance + RETURN_MARGIN
        out, row = guard_ranges(out, local, known, clearance, self.shield)
        phantoms = self.memory.phantoms(pose, now)
        if len(phantoms):
            out = out.copy()
            out[:2] = brake_returns(out[:2], phantoms, clearance, self.shield, radius=self.shield.human_radius)
            if row is None and not np.allclose(out, before, atol=1e-9):
                row = {"before": before.tolist(), "after": out.tolist()}
            if row is not None:
                row["after"], row["phantoms"] = out.tolist(), phantoms.tolist()
        return out, {**cols, "ranges": len(scan.points), "range_guard": row}
