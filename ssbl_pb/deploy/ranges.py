"""Pepper's base lasers and sonars as NAOqi publishes them in ALMemory: the keys, where each sensor sits on the
base, and the robot-frame points of their returns (``scan_points``). Deploy reads them (``naoqi.NaoqiRobot.ranges``,
one ``ALMemory.getListData`` of ``KEYS`` a tick); the virtual Pepper publishes the same keys (``virtual.robot``).

Lasers (ros-naoqi/naoqi_driver, src/converters/laser.cpp): Front, Left and Right, 15 segments each over a 60 deg
horizontal field (4 deg a segment). Each segment's return is a point (X along the laser's axis, Y to its left,
metres) in the laser's own frame, Seg01 the leftmost and Seg15 the rightmost (the driver reverses them for ROS's
right-to-left scan). Mounts are the driver's static transforms to base_footprint. Aldebaran's "Pepper - Lasers"
gives 6.66 frames a second per laser; naoqi_driver's default range is 0.1-3.0 m, and a segment that sees nothing
within it reports the point at the range's end. Between the lasers' fields lie blind sectors (30-70 deg either side
of straight ahead, and the rear 100 deg): the rear is the back sonar's.
Sonars (Aldebaran's "Pepper - Sonars"): Front and Back, each the distance (m) to the nearest echo in its 60 deg
cone, operational 0.15-2.5 m, reported up to 6.45 m (that value: nothing).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

LASER_KEY = "Device/SubDeviceList/Platform/LaserSensor/{}/Horizontal/Seg{:02d}/{}/Sensor/Value"
SONAR_KEY = "Device/SubDeviceList/Platform/{}/Sonar/Sensor/Value"


@dataclasses.dataclass(frozen=True)
class Mount:
    """A sensor's pose on the base (base_footprint frame: x forward, y left; metres, rad)."""

    x: float
    y: float
    yaw: float


# naoqi_driver's static transforms (laser.cpp: the front laser 0.056 m ahead, the side ones at (-0.018, +-0.090)
# turned +-1.757 rad); the sonars 0.07 m ahead and behind the base's centre, facing out ("Pepper - Sonars")
LASERS = {"Front": Mount(0.056, 0.0, 0.0), "Left": Mount(-0.018, 0.090, 1.757), "Right": Mount(-0.018, -0.090, -1.757)}
SONARS = {"Front": Mount(0.07, 0.0, 0.0), "Back": Mount(-0.07, 0.0, math.pi)}


@dataclasses.dataclass(frozen=True)
class RangeParams:
    """The sensors' fields, ranges and rates (sources in the module docstring)."""

    segments: int = 15
    laser_fov_deg: float = 60.0
    laser_min: float = 0.1  # m: naoqi_driver's default range
    laser_max: float = 3.0
    laser_hz: float = 6.66
    # m above the floor the lasers scan at: "Pepper - Lasers" puts the surroundings lasers 0.30 m below KneePitch,
    # itself ~0.33-0.39 m up (the base's top), so 0.03-0.09 m; 0.1 m keeps the virtual rays clear of the floor
    # and still at a person's shins
    laser_height: float = 0.1
    sonar_cone_deg: float = 60.0
    sonar_min: float = 0.15  # m: the operational range; returns outside it are not trusted
    sonar_max: float = 2.5
    sonar_reported_max: float = 6.45  # m: the value a sonar reports with no echo
    sonar_rays: int = 5  # rays the virtual Pepper casts across the cone (its nearest hit is the echo)
    # ours: the 10 Hz control rate, so each tick may see a new echo; an echo from 6.45 m returns in 38 ms
    sonar_hz: float = 10.0


RANGES = RangeParams()
LASER_KEYS = tuple(LASER_KEY.format(side, k, axis) for side in LASERS for k in range(1, RANGES.segments + 1)
                   for axis in "XY")
SONAR_KEYS = tuple(SONAR_KEY.format(side) for side in SONARS)
KEYS = LASER_KEYS + SONAR_KEYS  # 92: what one ``ALMemory.getListData`` reads


def segment_angles(p: RangeParams = RANGES) -> np.ndarray:
    """Each segment's centre angle in its laser's frame (rad, counter-clockwise), Seg01 (leftmost) first."""
    width = math.radians(p.laser_fov_deg) / p.segments
    return math.radians(p.laser_fov_deg) / 2 - (np.arange(p.segments) + 0.5) * width


def sonar_angles(p: RangeParams = RANGES) -> np.ndarray:
    """The directions across a sonar's cone (rad, in its frame) the virtual Pepper casts its rays along."""
    return np.linspace(-0.5, 0.5, p.sonar_rays) * math.radians(p.sonar_cone_deg)


def _to_base(mount: Mount, xy: np.ndarray) -> np.ndarray:
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    return xy @ np.array([[c, s], [-s, c]]) + np.array([mount.x, mount.y])


def in_laser_fields(points: np.ndarray, p: RangeParams = RANGES) -> np.ndarray:
    """Which robot-frame points (k, 2) lie inside a laser's field (its 60 deg, within its range)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.zeros(len(pts), dtype=bool)
    for m in LASERS.values():
        d = pts - [m.x, m.y]
        off = np.abs(np.remainder(np.arctan2(d[:, 1], d[:, 0]) - m.yaw + math.pi, 2 * math.pi) - math.pi)
        out |= (off <= math.radians(p.laser_fov_deg) / 2) & (np.hypot(d[:, 0], d[:, 1]) < p.laser_max)
    return out


def _numbers(values: Sequence[object]) -> np.ndarray:
    def number(v: object) -> float:
        try:
            return float(v)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return math.nan

    vals = np.array([number(v) for v in values], dtype=float)
    if len(vals) != len(KEYS):
        raise ValueError(f"ranges: {len(vals)} values for the {len(KEYS)} keys")
    return vals


def scan_points(values: Sequence[object], p: RangeParams = RANGES) -> tuple[np.ndarray, int]:
    """Robot-frame points (k, 2) of every return in the values of ``KEYS`` (in that order), and how many of them (the
    last) are sonar echoes: each laser segment within the laser's range, and each sonar echo within its
    operational range as a point on the sonar's axis (as naoqi_driver publishes it, a ROS Range; the echo may come
    from anywhere in the cone, but spread across it the front sonar's echo off a member the robot passed put phantom
    points in its way, and the front laser covers that cone in 15 segments). Missing or non-numeric values count as
    nothing seen."""
    vals = _numbers(values)
    out = []
    n = 2 * p.segments
    for i, mount in enumerate(LASERS.values()):
        xy = vals[i * n:(i + 1) * n].reshape(-1, 2)
        r = np.hypot(xy[:, 0], xy[:, 1])
        ok = np.isfinite(r) & (r >= p.laser_min) & (r < p.laser_max - 1e-3)
        out.append(_to_base(mount, xy[ok]))
    echoes = [_to_base(mount, np.array([[r, 0.0]])) for r, mount in zip(vals[len(LASER_KEYS):], SONARS.values(),
                                                                         strict=True)
              if np.isfinite(r) and p.sonar_min <= r <= p.sonar_max]
    return np.concatenate(out + echoes).reshape(-1, 2), len(echoes)
