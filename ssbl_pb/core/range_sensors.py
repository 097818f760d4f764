"""Pepper's base range sensors: where each laser and sonar sits on the base, their fields, ranges and rates, and
which places the lasers see (``in_laser_fields``). The virtual Pepper casts its rays from these; deploy's guards
brake for what they see (``deploy.ranges``: NAOqi's keys and the points of their returns).

Lasers (ros-naoqi/naoqi_driver, src/converters/laser.cpp): Front, Left and Right, 15 segments each over a 60 deg
horizontal field (4 deg a segment). Mounts are the driver's static transforms to base_footprint. Aldebaran's
"Pepper - Lasers" gives 6.66 frames a second per laser; naoqi_driver's default range is 0.1-3.0 m. Between the
lasers' fields lie blind sectors (30-70 deg either side of straight ahead, and the rear 100 deg): the rear is the
back sonar's.
Sonars (Aldebaran's "Pepper - Sonars"): Front and Back, each over a 60 deg cone, operational 0.15-2.5 m, reported
up to 6.45 m (that value: nothing).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .shield import ShieldParams, brake_returns


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

# m beyond the stop distance the range returns are braked for (0.5 m by default: the training shield's clearance,
# 0.05 m inside the deploy shield's for tracked people). A body seen as points on its surface blocks sliding round
# it at the clearance it is braked for (the points ahead on its arc close in), and tracked members are the shield's
# to keep at 0.55 m
RETURN_MARGIN = 0.05


def segment_angles(p: RangeParams = RANGES) -> np.ndarray:
    """Each segment's centre angle in its laser's frame (rad, counter-clockwise), Seg01 (leftmost) first."""
    width = math.radians(p.laser_fov_deg) / p.segments
    return math.radians(p.laser_fov_deg) / 2 - (np.arange(p.segments) + 0.5) * width


def sonar_angles(p: RangeParams = RANGES) -> np.ndarray:
    """The directions across a sonar's cone (rad, in its frame) the virtual Pepper casts its rays along."""
    return np.linspace(-0.5, 0.5, p.sonar_rays) * math.radians(p.sonar_cone_deg)


def in_laser_fields(points: np.ndarray, p: RangeParams = RANGES) -> np.ndarray:
    """Which robot-frame points (k, 2) lie inside a laser's field (its 60 deg, within its range)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.zeros(len(pts), dtype=bool)
    for m in LASERS.values():
        d = pts - [m.x, m.y]
        off = np.abs(np.remainder(np.arctan2(d[:, 1], d[:, 0]) - m.yaw + math.pi, 2 * math.pi) - math.pi)
        out |= (off <= math.radians(p.laser_fov_deg) / 2) & (np.hypot(d[:, 0], d[:, 1]) < p.laser_max)
    return out


def lasers_see_body(centres: np.ndarray, radius: float, p: RangeParams = RANGES) -> np.ndarray:
    """Which robot-frame body centres (k, 2) a laser sees: the body's middle or either side across the line of
    sight (``radius`` off) inside a laser's field."""
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    u = c / np.maximum(np.hypot(c[:, 0], c[:, 1]), 1e-9)[:, None]
    side = np.column_stack([-u[:, 1], u[:, 0]]) * radius
    return in_laser_fields(c, p) | in_laser_fields(c + side, p) | in_laser_fields(c - side, p)


def brake_for_bodies(velocity: np.ndarray, bodies: np.ndarray, clearance: float, shield: ShieldParams) -> np.ndarray:
    """The body velocity (vx, vy) braked as deploy's range guard brakes for the lasers' returns
    (``deploy.guards.guard_ranges``) for the people at robot-frame ``bodies`` (k, 2) that a laser sees
    (``lasers_see_body``): their returns on the body's circle (``shield.human_radius``; the virtual Pepper's lasers hit
    that cylinder), each closing speed cut to stop ``clearance`` from it (``shield.brake_returns``)."""
    pts = np.asarray(bodies, dtype=float).reshape(-1, 2)
    seen = lasers_see_body(pts, shield.human_radius)
    if not seen.any():
        return np.asarray(velocity, dtype=float)[:2].copy()
    return brake_returns(velocity, pts[seen], clearance, shield, radius=shield.human_radius)
