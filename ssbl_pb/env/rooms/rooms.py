"""Rooms: their size and obstacles (empty, randomly furnished, or read from a room YAML cut from a map).

A ``Room`` is a ``size_x`` x ``size_y`` rectangle centred on the origin with boxes inside it (``obstacles``'s rows)
and their distance field. Scenario names choose the room per episode (``scenarios``: ``@empty``, ``@furnished``,
``@map``): the empty room is ``WorldParams.room_size``; a furnished room is drawn by ``furnished_room`` (a side of
7-12 m, furniture of real sizes against the walls and free-standing); a map room is the room YAML of
``tools/import_map.py`` (its ``obstacles.boxes``, fitted to the map's occupied cells) or written by hand.
``free_component`` says which places a robot can reach from which (spawning starts it where it can drive to the
group). Numbers: docs/decisions.md, "Rooms with obstacles".
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from ...params import ConfigError, _check, _positive, load_yaml, plain
from .obstacles import CELL, box_rows, build_field, field_at

# furniture of an office or a lab: (name, size along the wall or its length, depth) in metres; each piece drawn
# is scaled by 0.8-1.2 (catalogue sizes of desks, tables, cabinets, shelves, sofas; a pillar and a plant pot)
FURNITURE = (("desk", 1.4, 0.7), ("table", 1.6, 0.9), ("small table", 0.8, 0.8), ("cabinet", 0.9, 0.45),
             ("shelf", 1.0, 0.35), ("sofa", 1.9, 0.9), ("armchair", 0.8, 0.8), ("pillar", 0.4, 0.4),
             ("plant", 0.45, 0.45))


@dataclasses.dataclass(frozen=True)
class FurnitureParams:
    """How ``furnished_room`` draws a room (env argument ``furniture``)."""

    size_min: float = 7.0  # m, each side: the smallest room that holds a group of 5 and the robot's start
    size_max: float = 14.0  # m: a large office or lab (the Willow Garage rooms are 5-15 m; its lab cut by
    #                         tools/import_map.py is 14 x 9 m)
    density_min: float = 0.03  # pieces per m^2 of floor: 3 in an empty-ish 10 x 10 m room ...
    density_max: float = 0.10  # ... 10 in a furnished one (the Willow Garage lab: ~12 per 100 m^2)
    against_wall: float = 0.5  # share of pieces standing against a wall (desks, shelves, sofas)
    turned: float = 0.3  # share of free-standing pieces turned by any angle (the others follow the walls)
    clutter_min: float = 0.0  # share of the floor covered by clutter (``_clutter``), drawn per room in
    clutter_max: float = 0.0  # [clutter_min, clutter_max]; none by default. Rooms cut from a SLAM map are 30-50 %
    #                          not free (occupied, unknown or speckle, much of it the walls' ragged outline:
    #                          docs/benchmarks.md), so the shipped policy trained with up to 0.25, then 0.35
    #                          (configs/shipped/vector_stage4.yaml, vector_stage5.yaml)

    def __post_init__(self) -> None:
        _positive("furniture", self, "size_min", "size_max")
        _check(self.size_min <= self.size_max, "furniture", "size_max", self.size_max,
               f">= size_min ({self.size_min})")
        _check(self.size_max <= 100, "furniture", "size_max", self.size_max, "<= 100 m")
        for name in ("density_min", "density_max", "against_wall", "turned", "clutter_min", "clutter_max"):
            v = getattr(self, name)
            _check(isinstance(v, int | float) and 0 <= v <= 1, "furniture", name, v, "a number in [0, 1]")
        _check(self.density_min <= self.density_max, "furniture", "density_max", self.density_max,
               f">= density_min ({self.density_min})")
        _check(self.clutter_min <= self.clutter_max <= 0.5, "furniture", "clutter_max", self.clutter_max,
               f">= clutter_min ({self.clutter_min}) and <= 0.5")


class Room:
    """A room: its size (m), its obstacles (``obstacles`` rows, room frame) and their distance field over the
    room (``field``: nodes ``(x0 + j CELL, y0 + i CELL)``). ``source``: 'empty', 'furnished' or the YAML path."""

    def __init__(self, size: tuple[float, float], rows: np.ndarray | None = None, source: str = "empty") -> None:
        self.size = (float(size[0]), float(size[1]))
        self.rows = np.zeros((0, 6)) if rows is None else np.ascontiguousarray(rows, dtype=float).reshape(-1, 6)
        self.source = source
        self.x0, self.y0 = -self.size[0] / 2, -self.size[1] / 2
        if len(self.rows):
            nx, ny = (int(math.ceil(s / CELL - 1e-9)) + 1 for s in self.size)
            self.field = np.empty((ny, nx), dtype=np.float32)
            build_field(self.rows, self.x0, self.y0, self.field)
        else:
            self.field = np.zeros((0, 0), dtype=np.float32)
        self._components: dict[float, np.ndarray] = {}

    @property
    def furnished(self) -> bool:
        return len(self.rows) > 0

    def boxes(self) -> np.ndarray:
        """Obstacles as (B, 5) ``(cx, cy, size_x, size_y, yaw)`` (drawing, PyBullet)."""
        r = self.rows
        return np.column_stack([r[:, 0], r[:, 1], 2 * r[:, 2], 2 * r[:, 3], np.arctan2(r[:, 5], r[:, 4])])

    def clearance_at(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the nearest obstacle as the field gives it (its cap where none is near)."""
        return float(field_at(self.field, self.x0, self.y0, x, y)) if self.furnished else math.inf

    def free_component(self, clearance: float) -> np.ndarray:
        """Labels (ny, nx) of the places whose centre keeps ``clearance`` from every obstacle and wall, connected
        (0: too close); two points with the same label are joined by a path keeping that clearance."""
        if clearance not in self._components:
            from scipy import ndimage

            ny, nx = self.field.shape
            xs, ys = self.x0 + CELL * np.arange(nx), self.y0 + CELL * np.arange(ny)
            inside = ((np.abs(xs)[None, :] <= self.size[0] / 2 - clearance)
                      & (np.abs(ys)[:, None] <= self.size[1] / 2 - clearance))
            self._components[clearance] = ndimage.label((self.field >= clearance) & inside)[0]
        return self._components[clearance]

    def component_at(self, clearance: float, x: float, y: float) -> int:
        """The label of ``free_component(clearance)`` at the node nearest (x, y) (0 outside the room)."""
        labels = self.free_component(clearance)
        j, i = int(round((x - self.x0) / CELL)), int(round((y - self.y0) / CELL))
        ny, nx = labels.shape
        return int(labels[i, j]) if 0 <= i < ny and 0 <= j < nx else 0


SIDES = (-1.0, 1.0)  # ``rng.choice(SIDES)``'s draw, made as ``rng.integers(2)`` at a tenth of the cost


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """``rng.uniform(low, high)``, the same number from the same draw, at a quarter of its call's cost."""
    return low + (high - low) * rng.random()


def furnished_room(rng: np.random.Generator, p: FurnitureParams) -> Room:
    """A random room: sides in [size_min, size_max], ``density`` pieces per m^2 of ``FURNITURE`` (scaled 0.8-1.2),
    a share against a wall (its back to it, anywhere along it), the rest free-standing anywhere, wall-aligned or
    (``turned``) at any angle, then clutter over a share of the floor in [clutter_min, clutter_max] (``_clutter``).
    Pieces may touch or overlap, as furniture stands in groups."""
    sx, sy = (float(_uniform(rng, p.size_min, p.size_max)) for _ in range(2))
    count = int(round(_uniform(rng, p.density_min, p.density_max) * sx * sy))
    boxes = []
    for _ in range(count):
        _, length, depth = FURNITURE[int(rng.integers(len(FURNITURE)))]
        length, depth = length * _uniform(rng, 0.8, 1.2), depth * _uniform(rng, 0.8, 1.2)
        if rng.random() < p.against_wall:
            wall = int(rng.integers(4))  # +x, -x, +y, -y
            along = sy if wall < 2 else sx
            t = _uniform(rng, -along / 2 + length / 2, along / 2 - length / 2)
            if wall < 2:
                x = (sx / 2 - depth / 2) * (1 if wall == 0 else -1)
                boxes.append((x, t, depth, length, 0.0))
            else:
                y = (sy / 2 - depth / 2) * (1 if wall == 2 else -1)
                boxes.append((t, y, length, depth, 0.0))
        else:
            yaw = _uniform(rng, 0, math.pi) if rng.random() < p.turned else math.pi / 2 * int(rng.integers(2))
            x, y = _uniform(rng, -sx / 2, sx / 2), _uniform(rng, -sy / 2, sy / 2)
            boxes.append((x, y, length, depth, yaw))
    boxes += _clutter(rng, sx, sy, _uniform(rng, p.clutter_min, p.clutter_max))
    return Room((sx, sy), box_rows(np.array(boxes).reshape(-1, 5)), "furnished")


def _clutter(rng: np.random.Generator, sx: float, sy: float, share: float) -> list[tuple[float, ...]]:
    """Blobs of small axis-aligned boxes covering about ``share`` of a ``sx`` x ``sy`` floor, as a SLAM map shows
    chairs, bins, cables and its own speckle: each blob 2-6 boxes of 0.1-0.6 m scattered 0.3 m (s.d.) around a
    centre, half of the blobs against a wall (the map's ragged wall outline)."""
    out: list[tuple[float, ...]] = []
    covered, target = 0.0, share * sx * sy
    while covered < target:
        if rng.random() < 0.5:
            cx, cy = _uniform(rng, -sx / 2, sx / 2), _uniform(rng, -sy / 2, sy / 2)
        elif rng.random() < 0.5:
            cx, cy = SIDES[int(rng.integers(2))] * (sx / 2 - _uniform(rng, 0.0, 0.4)), _uniform(rng, -sy / 2, sy / 2)
        else:
            cx, cy = _uniform(rng, -sx / 2, sx / 2), SIDES[int(rng.integers(2))] * (sy / 2 - _uniform(rng, 0.0, 0.4))
        for _ in range(int(rng.integers(2, 7))):
            w, h = rng.uniform(0.1, 0.6, 2)
            out.append((cx + rng.normal(0, 0.3), cy + rng.normal(0, 0.3), w, h, 0.0))
            covered += w * h
    return out


def read_obstacles(path: str | Path, data: dict[str, Any] | None = None) -> np.ndarray | None:
    """The ``obstacles.boxes`` of a room YAML as (B, 5) ``(cx, cy, size_x, size_y, yaw rad)`` (the file holds the
    yaw in degrees), or None when it has no ``obstacles`` section; ``ConfigError`` naming the file and box."""
    data = load_yaml(path) if data is None else data
    if "obstacles" not in data:
        return None
    obs = data["obstacles"]
    if not isinstance(obs, dict) or not isinstance(obs.get("boxes"), list):
        raise ConfigError(f"{path}: obstacles: expected a mapping with a 'boxes:' list of [x, y, size_x, size_y, "
                          f"yaw_deg] (room frame, metres)")
    out = []
    for k, b in enumerate(obs["boxes"]):
        ok = (isinstance(b, list) and len(b) == 5
              and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in b))
        if not ok or b[2] <= 0 or b[3] <= 0:
            raise ConfigError(f"{path}: obstacles.boxes[{k}] = {plain(b)!r}: expected [x, y, size_x, size_y, yaw_deg] "
                              f"with sizes > 0 (room frame, metres)")
        out.append((b[0], b[1], b[2], b[3], math.radians(b[4])))
    return np.array(out, dtype=float).reshape(-1, 5)
