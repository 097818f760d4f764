"""Import a ROS map_server occupancy grid (PGM + YAML) and cut the simulated room out of it.

Map frame: ``origin`` (x, y, yaw) is the pose of the lower-left pixel's corner, as map_server defines it;
image row 0 is the top. Occupancy follows map_server's trinary mode: ``p = (255 - v) / 255`` (``v / 255``
when ``negate``), occupied if ``p > occupied_thresh``, free if ``p < free_thresh``, unknown otherwise.

The room: the free space inside a chosen box and/or connected to a seed point, split at doorways
narrower than ``door_width`` so that a room does not leak into the corridor. Its bounding box gives the
wall-to-wall extent; the largest free axis-aligned rectangle inside it gives the furniture-free size.
Every cell inside the room's walls that is not its free space (occupied, unknown, or behind a door) becomes an
obstacle of the simulated room: the cells are merged into boxes (``obstacle_boxes``, row runs stacked), which the
room YAML carries (``obstacles.boxes``) and the env builds (``env.rooms.rooms``).
The room frame is centred on the chosen rectangle, axes parallel to the map image's.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..params import CalibrationError, WorldParams, from_dict, load_yaml
from .io import write_image


@dataclasses.dataclass
class OccupancyMap:
    """Trinary grid (int8: 1 occupied, 0 free, -1 unknown), row 0 at the top, and its map-frame placement."""

    grid: np.ndarray
    resolution: float
    origin: tuple[float, float, float]
    yaml_path: Path
    image_path: Path

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape  # type: ignore[return-value]

    def cell_to_map(self, rc: np.ndarray) -> np.ndarray:
        """(row, col) cell centres (N, 2) -> map-frame (x, y) metres."""
        rc = np.asarray(rc, dtype=float).reshape(-1, 2)
        h = self.grid.shape[0]
        lx = (rc[:, 1] + 0.5) * self.resolution
        ly = (h - rc[:, 0] - 0.5) * self.resolution
        c, s = math.cos(self.origin[2]), math.sin(self.origin[2])
        return np.stack([self.origin[0] + c * lx - s * ly, self.origin[1] + s * lx + c * ly], axis=1)

    def map_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Map-frame (x, y) -> image (u, v) pixel coordinates (float, u = column, v = row), for drawing."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2) - np.array(self.origin[:2])
        c, s = math.cos(self.origin[2]), math.sin(self.origin[2])
        lx, ly = c * xy[:, 0] + s * xy[:, 1], -s * xy[:, 0] + c * xy[:, 1]
        h = self.grid.shape[0]
        return np.stack([lx / self.resolution - 0.5, h - ly / self.resolution - 0.5], axis=1)


def _number(data: dict[str, Any], key: str, where: str, lo: float, hi: float, default: float | None = None
            ) -> float:
    if key not in data:
        if default is None:
            raise CalibrationError(f"{where}: missing key {key!r}")
        return default
    v = data[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or not lo <= v <= hi:
        raise CalibrationError(f"{where}: {key} = {v!r}: expected a number in [{lo}, {hi}]")
    return float(v)


def read_map(path: str | Path) -> OccupancyMap:
    """Read a map_server YAML and its image; errors name the file and the field."""
    path = Path(path)
    data = load_yaml(path)
    where = str(path)
    if "image" not in data or not isinstance(data["image"], str):
        raise CalibrationError(f"{where}: missing key 'image' (the PGM file name)")
    image = Path(data["image"])
    image = image if image.is_absolute() else path.parent / image
    res = _number(data, "resolution", where, 1e-4, 10.0)
    origin = data.get("origin")
    if (not isinstance(origin, list | tuple) or len(origin) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in origin)):
        raise CalibrationError(f"{where}: origin = {origin!r}: expected [x, y, yaw], three finite numbers")
    negate = data.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise CalibrationError(f"{where}: negate = {negate!r}: expected 0 or 1")
    occ = _number(data, "occupied_thresh", where, 0.0, 1.0, 0.65)
    free = _number(data, "free_thresh", where, 0.0, 1.0, 0.196)
    if free >= occ:
        raise CalibrationError(f"{where}: free_thresh {free} must be below occupied_thresh {occ}")
    if data.get("mode", "trinary") != "trinary":
        raise CalibrationError(f"{where}: mode {data.get('mode')!r}: only 'trinary' is supported")
    if not image.is_file():
        raise CalibrationError(f"{where}: image {data['image']!r} not found (looked for {image})")
    img = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise CalibrationError(f"{image}: not a readable image (from {where})")
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2)
    v = img.astype(float) / (65535.0 if img.dtype == np.uint16 else 255.0)
    p = v if negate else 1.0 - v
    grid = np.full(img.shape[:2], -1, np.int8)
    grid[p > occ] = 1
    grid[p < free] = 0
    return OccupancyMap(grid, res, (float(origin[0]), float(origin[1]), float(origin[2])), path, image)


def largest_rectangle(mask: np.ndarray) -> tuple[int, int, int, int]:
    """Largest axis-aligned all-True rectangle (row0, col0, row1, col1), exclusive ends (histogram method)."""
    h, w = mask.shape
    heights = np.zeros(w, int)
    best = (0, 0, 0, 0, 0)
    for r in range(h):
        heights = np.where(mask[r], heights + 1, 0)
        stack: list[int] = []
        for c in range(w + 1):
            cur = heights[c] if c < w else 0
            while stack and heights[stack[-1]] >= cur:
                top = stack.pop()
                left = stack[-1] + 1 if stack else 0
                area = int(heights[top]) * (c - left)
                if area > best[0]:
                    best = (area, r - int(heights[top]) + 1, left, r + 1, c)
            stack.append(c)
    return best[1:]


@dataclasses.dataclass
class Room:
    """The room cut from the map: extents in the map frame and the transform map <- room."""

    bounds: tuple[float, float, float, float]  # wall-to-wall free extent: xmin, ymin, xmax, ymax (map frame)
    free_rect: tuple[float, float, float, float]  # largest furniture-free rectangle (map frame)
    room_size: tuple[float, float]
    centre: tuple[float, float]  # room frame origin in the map frame (yaw = the map's)
    free_fraction: float  # free cells / bounding-box cells
    component: np.ndarray  # bool mask of the room's free cells (map image shape)
    cells: tuple[int, int, int, int] = (0, 0, 0, 0)  # rows and columns [r0, r1) x [c0, c1) of room_size


def _cell(m: OccupancyMap, xy: tuple[float, float], what: str) -> tuple[int, int]:
    col, row = (int(v) for v in np.floor(m.map_to_pixel(np.array(xy))[0] + 0.5))
    h, w = m.shape
    if not (0 <= row < h and 0 <= col < w):
        raise CalibrationError(f"{m.yaml_path}: {what} {tuple(xy)} lies outside the map")
    return row, col


def extract_room(m: OccupancyMap, seed: tuple[float, float] | None = None,
                 region: tuple[float, float, float, float] | None = None, door_width: float = 0.9,
                 size_from: str = "bounds") -> Room:
    """The free region around ``seed`` and/or inside ``region`` (xmin, ymin, xmax, ymax), map frame, metres.

    Without a seed the largest free component (inside the region) is taken. ``size_from`` "bounds" (wall to
    wall, the default) or "free" (largest rectangle free of furniture; SLAM maps of furnished rooms make it
    small) sets ``room_size``.
    """
    if size_from not in ("free", "bounds"):
        raise CalibrationError(f"size_from = {size_from!r}: expected 'free' or 'bounds'")
    if seed is None and region is None:
        raise CalibrationError("give a seed point or a region (or both)")
    free = (m.grid == 0).astype(np.uint8)
    if region is not None:
        x0, y0, x1, y1 = region
        if not (x1 > x0 and y1 > y0):
            raise CalibrationError(f"region {tuple(region)}: expected xmin ymin xmax ymax with max > min")
        corners = m.map_to_pixel(np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]]))
        c_lo, r_lo = np.maximum(np.floor(corners.min(axis=0) + 0.5).astype(int), 0)
        c_hi, r_hi = np.floor(corners.max(axis=0) + 0.5).astype(int)
        inside = np.zeros_like(free)
        inside[r_lo:r_hi, c_lo:c_hi] = 1
        free &= inside
        if not free.any():
            cells = m.grid[r_lo:r_hi, c_lo:c_hi]
            if cells.size and (cells == 1).all():
                raise CalibrationError(f"{m.yaml_path}: region {tuple(region)}: all its {cells.size} cells are "
                                       f"occupied; expected free space for the room")
            occupied, unknown = int((cells == 1).sum()), int((cells == -1).sum())
            raise CalibrationError(f"{m.yaml_path}: region {tuple(region)} holds no free cell ({occupied} occupied, "
                                   f"{unknown} unknown); expected free space for the room")
    k = max(1, int(round(door_width / 2 / m.resolution)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
    # cores: free cells at least door_width / 2 from anything else; a narrower door separates two cores
    # (an opening would not: the tips of discs on both sides reach through a thin wall's doorway)
    core = cv2.erode(free, kernel, borderValue=0)
    n, labels = cv2.connectedComponents(core, connectivity=4)
    if seed is not None:
        row, col = _cell(m, seed, "seed")
        lab = labels[row, col]
        if lab == 0:
            raise CalibrationError(f"{m.yaml_path}: seed {tuple(seed)} is not in open free space (cell state "
                                   f"{int(m.grid[row, col])}; 0 free, 1 occupied, -1 unknown; doors narrower "
                                   f"than {door_width} m are closed)")
    else:
        if n <= 1:
            raise CalibrationError(f"{m.yaml_path}: no free space wider than door_width {door_width} m")
        lab = 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))
    comp = labels == lab
    # grow the core back to the walls, but not into cells as close to another core (behind a door)
    others = cv2.dilate(((labels > 0) & ~comp).astype(np.uint8), kernel) > 0
    comp = (cv2.dilate(comp.astype(np.uint8), kernel) > 0) & (free > 0) & ~others
    rows, cols = np.nonzero(comp)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    fr = largest_rectangle(comp[r0:r1, c0:c1])
    fr = (fr[0] + r0, fr[1] + c0, fr[2] + r0, fr[3] + c0)

    def extent(ra: int, ca: int, rb: int, cb: int) -> tuple[float, float, float, float]:
        """Map-frame bounding box of the cells [ra, rb) x [ca, cb) (corners, so yaw is handled)."""
        corners = m.cell_to_map(np.array([[ra - 0.5, ca - 0.5], [ra - 0.5, cb - 0.5], [rb - 0.5, ca - 0.5],
                                          [rb - 0.5, cb - 0.5]]))
        return (float(corners[:, 0].min()), float(corners[:, 1].min()), float(corners[:, 0].max()),
                float(corners[:, 1].max()))

    bounds = extent(r0, c0, r1, c1)
    free_rect = extent(*fr)
    ra, ca, rb, cb = fr if size_from == "free" else (r0, c0, r1, c1)
    # sizes along the room's own axes (the image's), so a yawed map origin does not inflate them
    size = (round(float(cb - ca) * m.resolution, 3), round(float(rb - ra) * m.resolution, 3))
    mid = m.cell_to_map(np.array([[0.5 * (ra + rb) - 0.5, 0.5 * (ca + cb) - 0.5]]))[0]
    centre = (round(float(mid[0]), 3), round(float(mid[1]), 3))
    frac = float(comp[r0:r1, c0:c1].mean())
    return Room(bounds, free_rect, size, centre, frac, comp, (ra, rb, ca, cb))


def cell_boxes(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Axis-aligned boxes (r0, r1, c0, c1), exclusive ends, whose union is exactly the True cells of ``mask``:
    each row's runs of True cells, stacked onto the box above while the run spans the same columns."""
    open_boxes: dict[tuple[int, int], int] = {}  # (c0, c1) -> first row
    out = []
    h = mask.shape[0]
    for r in range(h + 1):
        runs = set()
        if r < h:
            row = np.concatenate([[False], mask[r], [False]]).astype(np.int8)
            edges = np.flatnonzero(np.diff(row))
            runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for span in [s for s in open_boxes if s not in runs]:
            out.append((open_boxes.pop(span), r, *span))
        for span in runs - set(open_boxes):
            open_boxes[span] = r
    return out


def obstacle_boxes(m: OccupancyMap, room: Room) -> np.ndarray:
    """The room's obstacles as (B, 5) boxes ``(x, y, size_x, size_y, yaw_deg)`` in the room frame: every cell of
    its ``room_size`` rectangle that is not its free space, merged by ``cell_boxes``."""
    r0, r1, c0, c1 = room.cells
    boxes = cell_boxes(~room.component[r0:r1, c0:c1])
    if not boxes:
        return np.zeros((0, 5))
    b = np.array(boxes, dtype=float) + [r0, r0, c0, c0]
    mid = m.cell_to_map(np.stack([(b[:, 0] + b[:, 1]) / 2 - 0.5, (b[:, 2] + b[:, 3]) / 2 - 0.5], axis=1))
    transform = {"x": room.centre[0], "y": room.centre[1], "yaw": float(m.origin[2])}
    xy = map_to_room(mid, transform)
    size = np.stack([b[:, 3] - b[:, 2], b[:, 1] - b[:, 0]], axis=1) * m.resolution
    return np.column_stack([np.round(xy, 3), np.round(size, 3), np.zeros(len(b))])


def room_yaml(m: OccupancyMap, room: Room, seed: tuple[float, float] | None,
              region: tuple[float, float, float, float] | None = None) -> dict[str, Any]:
    """The room YAML: WorldParams fields under ``world`` (validated), the map and the map <- room transform, and
    the room's obstacles (``obstacle_boxes``)."""
    world = {"room_size": [float(v) for v in room.room_size]}
    from_dict(WorldParams, {"room_size": tuple(world["room_size"])}, f"room from {m.yaml_path}")
    boxes = obstacle_boxes(m, room)
    return {
        "world": world,
        "map": {"yaml": str(m.yaml_path), "image": str(m.image_path), "resolution": m.resolution,
                "origin": [float(v) for v in m.origin]},
        "map_to_room": {"x": room.centre[0], "y": room.centre[1], "yaw": float(m.origin[2])},
        "region": {"seed": None if seed is None else [float(v) for v in seed],
                   "box": None if region is None else [float(v) for v in region],
                   "bounds": [round(v, 3) for v in room.bounds],
                   "free_rect": [round(v, 3) for v in room.free_rect],
                   "free_fraction": round(room.free_fraction, 3)},
        "obstacles": {"note": "cells inside the room's walls that are not its free space (occupied, unknown or "
                              "behind a door), merged into boxes: [x, y, size_x, size_y, yaw_deg], room frame, metres",
                      "boxes": [[float(v) for v in row] for row in boxes]},
    }


def room_figure(m: OccupancyMap, room: Room, path: str | Path, margin: float = 2.0, scale: int = 6) -> Path:
    """PNG of the map around the room: free white, occupied black, unknown grey, the room's free cells green,
    wall-to-wall bounds blue, the furniture-free rectangle green, the room frame's x (red) and y (blue) axes."""
    img = np.full((*m.shape, 3), 160, np.uint8)
    img[m.grid == 0] = (255, 255, 255)
    img[m.grid == 1] = (0, 0, 0)
    img[room.component] = (190, 240, 190)
    big = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)

    def px(xy: np.ndarray) -> np.ndarray:
        return np.round((m.map_to_pixel(xy) + 0.5) * scale).astype(int)

    for box, colour in ((room.bounds, (255, 0, 0)), (room.free_rect, (0, 160, 0))):
        a, b = px(np.array([[box[0], box[1]], [box[2], box[3]]]))
        cv2.rectangle(big, tuple(int(v) for v in a), tuple(int(v) for v in b), colour, 2)
    c = np.array(room.centre)
    o, ax, ay = px(np.array([c, c + [1.0, 0.0], c + [0.0, 1.0]]))
    cv2.arrowedLine(big, tuple(int(v) for v in o), tuple(int(v) for v in ax), (0, 0, 255), 2)
    cv2.arrowedLine(big, tuple(int(v) for v in o), tuple(int(v) for v in ay), (255, 0, 0), 2)
    lo, hi = px(np.array([[room.bounds[0] - margin, room.bounds[3] + margin],
                          [room.bounds[2] + margin, room.bounds[1] - margin]]))
    lo, hi = np.maximum(lo, 0), np.minimum(hi, [big.shape[1], big.shape[0]])
    crop = np.ascontiguousarray(big[lo[1]:hi[1], lo[0]:hi[0]])
    return write_image(path, crop)


def room_to_map(xy: np.ndarray, transform: dict[str, float]) -> np.ndarray:
    """Room-frame (x, y) points (N, 2), as the env reports them, -> map frame, for drawing paths on the map."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    c, s = math.cos(transform["yaw"]), math.sin(transform["yaw"])
    return np.stack([transform["x"] + c * xy[:, 0] - s * xy[:, 1], transform["y"] + s * xy[:, 0] + c * xy[:, 1]],
                    axis=1)


def map_to_room(xy: np.ndarray, transform: dict[str, float]) -> np.ndarray:
    """Map-frame (x, y) points (N, 2) -> the room frame (``room_to_map``'s inverse)."""
    d = np.asarray(xy, dtype=float).reshape(-1, 2) - [transform["x"], transform["y"]]
    c, s = math.cos(transform["yaw"]), math.sin(transform["yaw"])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
