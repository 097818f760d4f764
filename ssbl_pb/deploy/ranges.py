"""Pepper's base lasers and sonars as NAOqi publishes them in ALMemory: the keys and the robot-frame points of their
returns (``scan_points``; where each sensor sits and what it sees: ``core.range_sensors``). Deploy reads them
(``naoqi.NaoqiRobot.ranges``, one ``ALMemory.getListData`` of ``KEYS`` a tick); the virtual Pepper publishes the same
keys (``virtual.robot``).

Lasers (ros-naoqi/naoqi_driver, src/converters/laser.cpp): each segment's return is a point (X along the laser's
axis, Y to its left, metres) in the laser's own frame, Seg01 the leftmost and Seg15 the rightmost (the driver
reverses them for ROS's right-to-left scan); a segment that sees nothing within the range reports the point at the
range's end. Sonars: each the distance (m) to the nearest echo in its cone (6.45 m: nothing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core.range_sensors import LASERS, RANGES, SONARS, Mount, RangeParams

LASER_KEY = "Device/SubDeviceList/Platform/LaserSensor/{}/Horizontal/Seg{:02d}/{}/Sensor/Value"
SONAR_KEY = "Device/SubDeviceList/Platform/{}/Sonar/Sensor/Value"
LASER_KEYS = tuple(LASER_KEY.format(side, k, axis) for side in LASERS for k in range(1, RANGES.segments + 1)
                   for axis in "XY")
SONAR_KEYS = tuple(SONAR_KEY.format(side) for side in SONARS)
KEYS = LASER_KEYS + SONAR_KEYS  # 92: what one ``ALMemory.getListData`` reads


def _to_base(mount: Mount, xy: np.ndarray) -> np.ndarray:
    c, s = math.cos(mount.yaw), math.sin(mount.yaw)
    return xy @ np.array([[c, s], [-s, c]]) + np.array([mount.x, mount.y])


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
