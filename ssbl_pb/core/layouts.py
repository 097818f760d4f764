"""Where a conversation group's members stand at spawn: the group models and the calibrated group data.

Two models (``GROUP_MODELS``), chosen with the env's ``groups`` argument:

* ``calibrated`` (default): the paper's formations (``formation_angles``) with the size and the
  irregularity of real groups. Per group: an irregularity ``c`` and a mean member-to-centroid distance ``r`` are
  drawn from the real groups of that size (``GroupData``, inverse-CDF sampling of stored quantiles); each
  member's radius and angle are jittered by ``c`` (radius x (1 + c z), angle + c (2 pi / n) z', z standardised
  normal draws), then the layout is scaled so its mean member-to-centroid distance is ``r``. A draw that puts
  two members' bodies into each other (closer than two body radii) is redrawn. docs/decisions.md
  ("Groups as real people stand") has the figures against the real data.
* ``paper``: the original code's o-space circle (1.0 m, grown for larger groups, ``SocialParams``).

The formation ``real`` (scenario ``real``) places the members exactly as in an annotated real frame, re-centred
on their centroid and rotated at random, whatever the model.

``GroupData`` is read from a groups YAML (``tools/calibrate_groups.py``); the one shipped in ``ssbl_pb/data``
is the default. ``load_group_data`` validates it: errors name the file and the field.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import UserError
from ..params import FORMATIONS, ConfigError, SocialParams, load_yaml

GROUP_MODELS = ("calibrated", "paper")
LAYOUTS = (*FORMATIONS, "real")
SHIPPED_GROUPS = Path(__file__).resolve().parents[1] / "data" / "groups.yaml"
DISTANCES = ("centroid_distance_m", "nearest_neighbour_m")
ROBOT_ROOM = 0.5  # share of a person's room a robot newcomer gets (CongreG8; docs/decisions.md)


def formation_angles(formation: str, n: int, social: SocialParams) -> np.ndarray:
    """Members' angles (rad) around the o-space centre, before a random rotation.

    circular: evenly spaced; vis_a_vis: two facing clusters; l_shape: each member 90 deg further along
    (2 members make an L, 3 a U); side_by_side: adjacent members at the closest comfortable spacing.
    """
    if formation not in FORMATIONS:
        raise UserError(f"formation {formation!r}: expected one of {FORMATIONS}")
    if not 2 <= n <= 5:
        raise UserError(f"group size {n}: expected 2 to 5 members")
    radius = social.ospace_radius_for(n)
    delta = 2.0 * math.asin(min(1.0, social.min_member_gap / (2.0 * radius)))  # neighbours min_member_gap apart
    if formation == "circular":
        return 2.0 * math.pi * np.arange(n) / n
    if formation == "side_by_side":
        return delta * np.arange(n)
    if formation == "l_shape":
        return min(max(math.pi / 2, delta), 2.0 * math.pi / n) * np.arange(n)
    a, b = (n + 1) // 2, n // 2  # vis_a_vis
    side_a = (np.arange(a) - (a - 1) / 2.0) * delta
    side_b = math.pi + (np.arange(b) - (b - 1) / 2.0) * delta
    return np.concatenate([side_a, side_b])


@dataclasses.dataclass(frozen=True)
class SizeData:
    """Real groups of one size: quantiles of each distribution and the layouts themselves (m, re-centred)."""

    groups: int
    centroid_distance_m: tuple[float, ...]
    nearest_neighbour_m: tuple[float, ...]
    irregularity: tuple[float, ...]
    orientation_offset_deg: tuple[float, ...] | None
    layouts: tuple[np.ndarray, ...]


@dataclasses.dataclass(frozen=True)
class GroupData:
    """A groups YAML: the quantile levels (percent) and the data per group size."""

    path: str
    quantiles: tuple[float, ...]
    sizes: dict[int, SizeData]

    def size(self, n: int, field: str = "") -> SizeData:
        """The data for groups of ``n``; a size the file lacks raises, naming the file and field."""
        if n not in self.sizes:
            raise ConfigError(f"{self.path}: sizes.{n}: missing; groups of {n} need real groups of that size "
                              f"(the file has sizes {sorted(self.sizes)})")
        data = self.sizes[n]
        if field == "layouts" and not data.layouts:
            raise ConfigError(f"{self.path}: sizes.{n}.layouts: empty; the 'real' layout needs real groups")
        return data

    def draw(self, rng: np.random.Generator, values: tuple[float, ...]) -> float:
        """One draw from the distribution given by its quantiles (piecewise-linear inverse CDF)."""
        return float(np.interp(rng.uniform(0.0, 100.0), self.quantiles, values))


def _numbers(path: str, field: str, value: Any, count: int | None, low: float | None, what: str) -> tuple:
    ok = isinstance(value, list) and all(isinstance(v, int | float) and not isinstance(v, bool)
                                         and math.isfinite(v) for v in value)
    if not ok or (count is not None and len(value) != count):
        size = f"{count} " if count is not None else ""
        raise ConfigError(f"{path}: {field} = {value!r}: expected a list of {size}finite numbers ({what})")
    if low is not None and any(v < low for v in value):
        raise ConfigError(f"{path}: {field} = {value!r}: expected values >= {low} ({what})")
    return tuple(float(v) for v in value)


def _size_data(path: str, n: int, entry: Any, levels: int) -> SizeData:
    where = f"sizes.{n}"
    if not isinstance(entry, dict):
        raise ConfigError(f"{path}: {where}: expected a mapping of distributions, got {entry!r}")
    required = ("groups", *DISTANCES, "irregularity")
    for key in required:
        if key not in entry:
            raise ConfigError(f"{path}: {where}.{key}: missing (each size needs {list(required)})")
    unknown = sorted(set(entry) - {*required, "orientation_offset_deg", "layouts"})
    if unknown:
        raise ConfigError(f"{path}: {where}: unknown key(s) {unknown}")
    if not isinstance(entry["groups"], int) or entry["groups"] < 1:
        raise ConfigError(f"{path}: {where}.groups = {entry['groups']!r}: expected an integer >= 1")
    dist = {}
    for key in DISTANCES:
        q = _numbers(path, f"{where}.{key}", entry[key], levels, 0.0, "metres, one per quantile level")
        if q[0] <= 0.0 or any(b < a for a, b in zip(q, q[1:], strict=False)):
            raise ConfigError(f"{path}: {where}.{key} = {list(q)}: expected positive distances, non-decreasing")
        dist[key] = q
    irr = _numbers(path, f"{where}.irregularity", entry["irregularity"], levels, 0.0, "one per quantile level")
    orient = entry.get("orientation_offset_deg")
    if orient is not None:
        orient = _numbers(path, f"{where}.orientation_offset_deg", orient, levels, 0.0, "degrees")
    layouts = []
    for k, flat in enumerate(entry.get("layouts") or []):
        xy = _numbers(path, f"{where}.layouts[{k}]", flat, 2 * n, None, f"x, y of {n} members in metres")
        layouts.append(np.array(xy).reshape(n, 2))
    return SizeData(entry["groups"], dist[DISTANCES[0]], dist[DISTANCES[1]], irr, orient, tuple(layouts))


@functools.lru_cache(maxsize=8)
def _load_cached(path: str, mtime: float) -> GroupData:
    return parse_group_data(load_yaml(path), path)


def parse_group_data(data: dict[str, Any], path: str) -> GroupData:
    """Check a groups YAML's content (``path`` names it in errors)."""
    q = data.get("quantiles")
    q = _numbers(path, "quantiles", q, None, 0.0, "percent levels from 0 to 100, increasing")
    if len(q) < 2 or q[0] != 0.0 or q[-1] != 100.0 or any(b <= a for a, b in zip(q, q[1:], strict=False)):
        raise ConfigError(f"{path}: quantiles = {list(q)}: expected increasing percent levels from 0 to 100")
    sizes = data.get("sizes")
    if not isinstance(sizes, dict) or not sizes:
        raise ConfigError(f"{path}: sizes: missing or empty (expected a mapping from group size to its data)")
    out = {}
    for key, entry in sizes.items():
        if not isinstance(key, int) or isinstance(key, bool) or key < 2:
            raise ConfigError(f"{path}: sizes.{key}: expected an integer group size >= 2")
        out[key] = _size_data(path, key, entry, len(q))
    return GroupData(path, q, out)


def load_group_data(path: str | Path | None = None) -> GroupData:
    """Read and check a groups YAML (default: the one shipped with the package); cached per file version."""
    p = Path(path) if path is not None else SHIPPED_GROUPS
    if not p.is_file():
        raise ConfigError(f"{p}: groups file not found (write one with tools/calibrate_groups.py)")
    return _load_cached(str(p), p.stat().st_mtime)


@dataclasses.dataclass(frozen=True)
class Layout:
    """A spawned group relative to its conversation centre: members' offsets (n, 2) and rest radii (n,), facing
    (n,) rad, the group's o-space radius and the radius it widens to once the robot has joined."""

    offsets: np.ndarray
    ring: np.ndarray
    yaw: np.ndarray
    radius: float
    joined_radius: float
    paper: bool = False  # the original's circle: the robot's place stays on the ring, and the centre moves
    #                      toward a joining robot as toward a member (``humans.Group``)


def body_radii(social: SocialParams, robot_radius: float) -> float:
    """Centre distance (m) at which a member's body and the robot's (its footprint's mean radius) touch."""
    return social.human_radius + robot_radius


def member_keep_out(social: SocialParams, reach: float, intimate_zone: float) -> float:
    """Centre distance from a member at which the footprint's farthest corner (``reach``), whatever the robot's
    heading, touches the member's intimate zone: their body radius + ``reach`` + the zone (0.95 m)."""
    return social.human_radius + reach + intimate_zone


def slot_keep(social: SocialParams, reach: float, intimate_zone: float, margin: float) -> float:
    """Centre distance the robot's place keeps from every member of a non-paper layout: ``member_keep_out`` plus
    ``margin`` (``TaskParams.route_margin``, the room to correct the shaping's route keeps too): 1.2 m."""
    return member_keep_out(social, reach, intimate_zone) + margin


def facing_centre(offsets: np.ndarray) -> np.ndarray:
    """Members' headings (rad, in [0, 2 pi)) toward the centre their offsets are measured from."""
    return np.mod(np.arctan2(-offsets[:, 1], -offsets[:, 0]), 2.0 * math.pi)


def person_growth(n: int) -> float:
    """How much a group of ``n`` widens for one more person (relative): a ring with the same spacing for n + 1."""
    return math.sin(math.pi / n) / math.sin(math.pi / (n + 1)) - 1.0


def free_layout(offsets: np.ndarray) -> Layout:
    """A non-paper group standing at ``offsets`` (n, 2) from its centre: each member's ring is its own distance,
    the o-space radius their mean, widened by ``ROBOT_ROOM`` of a person's room once the robot joins."""
    return _free_layout(np.asarray(offsets, dtype=float).reshape(-1, 2))


def _free_layout(offsets: np.ndarray) -> Layout:
    ring = np.hypot(offsets[:, 0], offsets[:, 1])
    radius = float(ring.mean())
    return Layout(offsets, ring, facing_centre(offsets), radius, radius * (1.0 + ROBOT_ROOM * person_growth(len(ring))))


def paper_layout(formation: str, n: int, social: SocialParams, rotation: float) -> Layout:
    """The original's layout: members on the o-space circle of ``social.ospace_radius_for(n)``."""

    angles = formation_angles(formation, n, social) + rotation
    radius = social.ospace_radius_for(n)
    offsets = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return Layout(offsets, np.full(n, radius), np.mod(angles + math.pi, 2.0 * math.pi), radius,
                  max(radius, social.ospace_radius_for(n + 1)), paper=True)


def _standard(rng: np.random.Generator, n: int) -> np.ndarray:
    z = rng.normal(size=n)
    return (z - z.mean()) / max(float(z.std()), 1e-9)


def calibrated_layout(formation: str, n: int, social: SocialParams, data: GroupData,
                      rng: np.random.Generator) -> Layout:
    """A formation with the size and irregularity of real groups of ``n`` (see the module docstring)."""

    sd = data.size(n)
    base = formation_angles(formation, n, social) + rng.uniform(0, 2 * math.pi)
    for _ in range(100):
        c = data.draw(rng, sd.irregularity) if n > 2 else 0.0
        radii = np.clip(1.0 + c * _standard(rng, n), 0.3, 3.0) if n > 2 else np.ones(n)
        angles = base + (c * 2.0 * math.pi / n) * _standard(rng, n) if n > 2 else base
        offsets = radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        to_centroid = offsets - offsets.mean(axis=0)
        offsets *= data.draw(rng, sd.centroid_distance_m) / np.hypot(*to_centroid.T).mean()
        gaps = np.hypot(*(offsets[:, None] - offsets[None]).transpose(2, 0, 1))
        if gaps[~np.eye(n, dtype=bool)].min() >= 2.0 * social.human_radius:
            break
    return _free_layout(offsets)


def real_layout(n: int, data: GroupData, rng: np.random.Generator) -> Layout:
    """A real group of ``n`` as annotated, re-centred on its centroid, turned by a random angle."""
    layouts = data.size(n, "layouts").layouts
    xy = layouts[int(rng.integers(len(layouts)))]
    a = rng.uniform(0, 2 * math.pi)
    c, s = math.cos(a), math.sin(a)
    xy = (xy - xy.mean(axis=0)) @ np.array([[c, s], [-s, c]])
    return _free_layout(xy)


@dataclasses.dataclass(frozen=True)
class GroupModel:
    """The env's group model: ``name`` in ``GROUP_MODELS`` and the real-group data it draws from."""

    name: str = "calibrated"
    data_path: str | None = None  # a groups YAML; None = the shipped one
    loaded: GroupData | None = dataclasses.field(default=None, compare=False, repr=False)  # data in hand

    def __post_init__(self) -> None:
        if self.name not in GROUP_MODELS:
            raise ConfigError(f"groups = {self.name!r}: expected one of {GROUP_MODELS}")

    @property
    def data(self) -> GroupData:
        return self.loaded if self.loaded is not None else load_group_data(self.data_path)

    def check_sizes(self, sizes: set[int], formations: set[str]) -> None:
        """Fail early (naming the file and field) when the data lack a size the scenario spawns."""
        if self.name == "calibrated" or "real" in formations:
            for n in sorted(sizes):
                self.data.size(n, "layouts" if "real" in formations else "")

    def layout(self, formation: str, n: int, social: SocialParams, rng: np.random.Generator) -> Layout:
        """One group's layout (consumes ``rng``; the paper model draws only its rotation, as before)."""
        if formation == "real":
            return real_layout(n, self.data, rng)
        if formation not in FORMATIONS:
            raise UserError(f"formation {formation!r}: expected one of {LAYOUTS}")
        if self.name == "paper":
            return paper_layout(formation, n, social, rng.uniform(0, 2 * math.pi))
        return calibrated_layout(formation, n, social, self.data, rng)
