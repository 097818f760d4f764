"""Static obstacles inside the room (furniture, a map's occupied cells) and the planar queries on them, compiled.

Obstacles are boxes, rows ``(cx, cy, half_x, half_y, cos yaw, sin yaw)`` in the room frame (``box_rows``). One
representation serves every query: the **distance field**, the signed distance (m, negative inside a box) from
the nodes of a grid of ``CELL`` m over the room to the nearest box, capped at ``CAP`` (``build_field``), read
between nodes by bilinear interpolation (``field_at``: exact along a box's face, at most a quarter ``CELL`` too far
near a box's corner, up to half a cell too near where two faces are equally near). On it:

* ``footprint_clearance``: the gap between Pepper's footprint and the nearest obstacle (collisions end the episode,
  the obstacle-clearance metric);
* ``ray_range`` / ``fill_scan``: the range scan of the Vector observation (a cone per sector traced through the
  field, and the room's walls);
* spawning asks ``boxes_distance`` (exact, every box) whether a group's disc is free.

The room's four walls are not in the field: they stay exact (``base.wall_clearance``). A room without obstacles
has no field: the queries are skipped (``use_field`` false) and cost nothing.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CELL = 0.05  # m between field nodes: a tenth of the footprint's width, the SLAM map's cells are 0.05-0.1 m
PER_CELL = 1.0 / CELL  # nodes per metre (a product where a quotient would be slower in the scan's loop)
CAP = 1.0  # m: the field stores distances up to this; a ray then advances at most 1 m per look-up
BOX_FIELDS = 6
HIT = 0.005  # m: a ray whose field value falls below this has hit
MIN_STEP = 0.01  # m: the least a ray advances (a ray grazing a face still ends)
EDGE_SPACING = 0.05  # m between the footprint's coarse samples (then refined around the nearest)
EXACT_BELOW = 0.5  # m: footprint clearances up to this are exact (a bound beyond: ``footprint_clearance``)


def box_rows(boxes: np.ndarray) -> np.ndarray:
    """(B, 5) boxes ``(cx, cy, size_x, size_y, yaw)`` (metres, radians) -> (B, 6) rows as the queries read them."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 5)
    return np.column_stack([b[:, 0], b[:, 1], b[:, 2] / 2, b[:, 3] / 2, np.cos(b[:, 4]), np.sin(b[:, 4])])


@njit(cache=True)
def box_distance(x: float, y: float, b: np.ndarray) -> float:
    """Signed distance (m) from (x, y) to the box row ``b`` (negative inside: minus the depth)."""
    dx, dy = x - b[0], y - b[1]
    lx = abs(b[4] * dx + b[5] * dy) - b[2]
    ly = abs(-b[5] * dx + b[4] * dy) - b[3]
    if lx > 0.0 or ly > 0.0:
        return math.hypot(max(lx, 0.0), max(ly, 0.0))
    return max(lx, ly)


@njit(cache=True)
def boxes_distance(x: float, y: float, boxes: np.ndarray) -> float:
    """Distance (m) from (x, y) to the nearest of ``boxes`` (inf without boxes), exact."""
    best = np.inf
    for k in range(boxes.shape[0]):
        d = box_distance(x, y, boxes[k])
        if d < best:
            best = d
    return best


@njit(cache=True)
def build_field(boxes: np.ndarray, x0: float, y0: float, out: np.ndarray) -> None:
    """The capped signed distance field of ``boxes`` at the nodes ``(x0 + j CELL, y0 + i CELL)`` of ``out``
    (ny, nx), written in place. Each box updates only the nodes within ``CAP`` of its bounding box."""
    ny, nx = out.shape
    out[:, :] = CAP
    for k in range(boxes.shape[0]):
        b = boxes[k]
        ex = abs(b[4]) * b[2] + abs(b[5]) * b[3] + CAP  # half extent of the box's reach along x and y
        ey = abs(b[5]) * b[2] + abs(b[4]) * b[3] + CAP
        j0, j1 = max(int(math.floor((b[0] - ex - x0) / CELL)), 0), min(int(math.ceil((b[0] + ex - x0) / CELL)), nx - 1)
        i0, i1 = max(int(math.floor((b[1] - ey - y0) / CELL)), 0), min(int(math.ceil((b[1] + ey - y0) / CELL)), ny - 1)
        c, s, hx, hy = b[4], b[5], b[2], b[3]
        for i in range(i0, i1 + 1):
            dy = y0 + i * CELL - b[1]
            row_x, row_y = s * dy, c * dy  # ``box_distance``'s terms of the row, then a square root for its hypot
            for j in range(j0, j1 + 1):
                dx = x0 + j * CELL - b[0]
                lx = abs(c * dx + row_x) - hx
                ly = abs(row_y - s * dx) - hy
                if lx > 0.0 or ly > 0.0:
                    mx, my = max(lx, 0.0), max(ly, 0.0)
                    d = math.sqrt(mx * mx + my * my)
                else:
                    d = max(lx, ly)
                if d < out[i, j]:
                    out[i, j] = d


@njit(cache=True)
def field_at(field: np.ndarray, x0: float, y0: float, x: float, y: float) -> float:
    """The field at (x, y), interpolated bilinearly; points beyond the grid read its border."""
    ny, nx = field.shape
    u = min(max((x - x0) * PER_CELL, 0.0), nx - 1.000001)
    v = min(max((y - y0) * PER_CELL, 0.0), ny - 1.000001)
    j, i = int(u), int(v)
    fu, fv = u - j, v - i
    a = field[i, j] + (field[i, j + 1] - field[i, j]) * fu
    b = field[i + 1, j] + (field[i + 1, j + 1] - field[i + 1, j]) * fu
    return a + (b - a) * fv


@njit(cache=True)
def footprint_clearance(field: np.ndarray, x0: float, y0: float, x: float, y: float, yaw: float,
                        half_length: float, half_width: float) -> float:
    """Gap (m) between the footprint (a box of these half extents at (x, y) turned by ``yaw``) and the nearest
    obstacle, negative when overlapping; ``CAP`` when nothing is within it. Its outline is sampled every
    ``EDGE_SPACING`` and the nearest sample refined by a ternary search along its edge (the distance to a corner
    or a face is convex along a straight edge). Farther than ``EXACT_BELOW`` from the footprint's circumscribed
    circle, the field at the centre minus the circle's radius is returned: a lower bound (the field is a
    distance: no point of the footprint is nearer), itself beyond ``EXACT_BELOW``, at a tenth of the cost;
    collisions and near passes are measured exactly (the minimum-clearance metric reads "at least 0.5 m" above)."""
    reach = math.hypot(half_length, half_width)
    far = field_at(field, x0, y0, x, y) - reach
    if far > EXACT_BELOW:
        return min(far, CAP)
    c, s = math.cos(yaw), math.sin(yaw)
    cx = (half_length, -half_length, -half_length, half_length)
    cy = (half_width, half_width, -half_width, -half_width)
    best, best_edge, best_t, best_step = np.inf, 0, 0.0, 1.0
    for e in range(4):  # edge e runs from corner e to corner e + 1
        ax, ay = x + c * cx[e] - s * cy[e], y + s * cx[e] + c * cy[e]
        f = (e + 1) % 4
        bx, by = x + c * cx[f] - s * cy[f], y + s * cx[f] + c * cy[f]
        n = max(int(math.ceil(math.hypot(bx - ax, by - ay) / EDGE_SPACING)), 1)
        for k in range(n):
            t = k / n
            d = field_at(field, x0, y0, ax + (bx - ax) * t, ay + (by - ay) * t)
            if d < best:
                best, best_edge, best_t, best_step = d, e, t, 1.0 / n
    if best >= CAP:
        return CAP
    e, f = best_edge, (best_edge + 1) % 4
    ax, ay = x + c * cx[e] - s * cy[e], y + s * cx[e] + c * cy[e]
    bx, by = x + c * cx[f] - s * cy[f], y + s * cx[f] + c * cy[f]
    lo, hi = max(best_t - best_step, 0.0), min(best_t + best_step, 1.0)
    for _ in range(12):  # the bracket shrinks to (2/3)^12 of two samples: < 1 mm
        m1, m2 = lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0
        d1 = field_at(field, x0, y0, ax + (bx - ax) * m1, ay + (by - ay) * m1)
        d2 = field_at(field, x0, y0, ax + (bx - ax) * m2, ay + (by - ay) * m2)
        if d1 < d2:
            hi = m2
        else:
            lo = m1
        best = min(best, d1, d2)
    return best


@njit(cache=True)
def wall_range(x: float, y: float, ux: float, uy: float, room_x: float, room_y: float, spread: float) -> float:
    """Distance (m) from (x, y) to the nearest wall point within ``spread`` rad of the unit direction (ux, uy), in a
    ``room_x`` x ``room_y`` room centred on the origin (0 from outside it): for each wall its perpendicular distance
    over the cosine of the sector's angle nearest its normal."""
    return _wall_range(x, y, ux, uy, room_x, room_y, math.cos(spread), math.sin(spread))


@njit(cache=True)
def _wall_range(x: float, y: float, ux: float, uy: float, room_x: float, room_y: float, cos_s: float,
                sin_s: float) -> float:
    """``wall_range`` with the spread's cosine and sine given (a scan computes them once)."""
    t = np.inf
    for w in range(4):
        c = ux if w == 0 else -ux if w == 1 else uy if w == 2 else -uy  # cosine to the wall's outward normal
        gap = (room_x / 2 - x) if w == 0 else (x + room_x / 2) if w == 1 else (room_y / 2 - y) if w == 2 \
            else (y + room_y / 2)
        # cosine of the sector's angle nearest the normal: 1 inside the sector, else cos(angle - spread)
        near = 1.0 if c >= cos_s else c * cos_s + math.sqrt(max(1.0 - c * c, 0.0)) * sin_s
        if near > 1e-9:
            t = min(t, max(gap, 0.0) / near)
    return t


@njit(cache=True)
def ray_range(use_field: bool, field: np.ndarray, x0: float, y0: float, x: float, y: float, ux: float, uy: float,
              max_range: float, room_x: float, room_y: float, spread: float) -> float:
    """Range (m) from (x, y) to the nearest obstacle or wall within ``spread`` rad of the direction (ux, uy) (a
    sector, as a laser's beams min-pooled into one reading; 0: a single ray), at most ``max_range``. Obstacles: a
    cone traced through the field: at axis distance ``t`` the sector is ``t tan(spread)`` wide, each step as long
    as the free distance beyond that width allows (at least ``MIN_STEP``); where the cone touches an obstacle, the
    range of the touched point (found down the field's gradient; never less than the axis distance reached) is
    returned: the axis distance alone read a wall straight ahead 12 % short with 24 sectors. The cone's tip is
    round (a disc around the axis point), so it may touch a point ahead before a nearer one at the sector's edge:
    the range is then at most ``tan(spread)`` (13 %) beyond the sector's nearest point, measured 3 % in a map room.
    Without ``use_field`` (no obstacles) only the walls count. A single ray (the scan before) slipped between small
    obstacles (a map's 5 cm speckle) until the robot's footprint was on them."""
    widen = math.tan(spread)
    ux_, uy_ = np.full(1, ux), np.full(1, uy)
    reach = np.full(1, min(max_range, wall_range(x, y, ux, uy, room_x, room_y, spread)))
    if use_field:
        _march_cones(field, x0, y0, x, y, ux_, uy_, widen, 0.0, reach)
    return reach[0]


@njit(cache=True)
def _march_cones(field: np.ndarray, x0: float, y0: float, x: float, y: float, ux: np.ndarray, uy: np.ndarray,
                 widen: float, free: float, reach: np.ndarray) -> None:
    """Trace the cones of half-width ``widen`` (its tangent) along the unit directions ``(ux[k], uy[k])`` through the
    field, each from where its round tip reaches ``free`` (the radius around (x, y) known to hold no obstacle) to
    ``reach[k]`` (its walls' range, at most the scan's), which gets the range found (``ray_range``'s rule).
    The cones advance in turn, a step each, so that the processor overlaps their independent look-ups (a third
    faster than one cone after the other, the same ranges)."""
    shrink = 1.0 / (1.0 + widen)
    rays = ux.shape[0]
    t = np.full(rays, max(free, 0.0) * shrink)
    done = np.zeros(rays, dtype=np.bool_)
    left = rays
    while left > 0:
        for k in range(rays):
            if done[k]:
                continue
            tk = t[k]
            if tk >= reach[k]:  # nothing in the cone within its reach
                done[k], left = True, left - 1
                continue
            px, py = x + ux[k] * tk, y + uy[k] * tk
            f = field_at(field, x0, y0, px, py)
            if f - tk * widen < HIT:
                if widen > 0.0:
                    reach[k] = min(max(_nearest_range(field, x0, y0, x, y, px, py, f), tk), reach[k])
                else:
                    reach[k] = tk
                done[k], left = True, left - 1
                continue
            t[k] = tk + max((f - tk * widen) * shrink, MIN_STEP)


@njit(cache=True)
def _nearest_range(field: np.ndarray, x0: float, y0: float, x: float, y: float, px: float, py: float,
                   f: float) -> float:
    """Range from (x, y) to the obstacle point nearest (px, py), ``f`` away down the field's gradient (central
    differences over one cell): where a cone stopped, the point it touched."""
    gx = field_at(field, x0, y0, px + CELL, py) - field_at(field, x0, y0, px - CELL, py)
    gy = field_at(field, x0, y0, px, py + CELL) - field_at(field, x0, y0, px, py - CELL)
    norm = math.hypot(gx, gy)
    if norm < 1e-9:
        return math.hypot(px - x, py - y)
    return math.hypot(px - f * gx / norm - x, py - f * gy / norm - y)


@njit(cache=True)
def fill_scan(o: np.ndarray, start: int, rays: int, use_field: bool, field: np.ndarray, x0: float, y0: float, x: float,
              y: float, frame_yaw: float, max_range: float, room_x: float, room_y: float) -> None:
    """``rays`` sector ranges over 360 deg into ``o[start:start + rays]``, sector k centred on ``frame_yaw + 2 pi k /
    rays`` (sector 0 along the frame's x) and ``2 pi / rays`` wide, each divided by ``max_range`` (1 = nothing within
    range)."""
    spread = math.pi / rays
    widen, cos_s, sin_s = math.tan(spread), math.cos(spread), math.sin(spread)
    ux, uy, reach = np.empty(rays), np.empty(rays), np.empty(rays)
    c, s = math.cos(frame_yaw), math.sin(frame_yaw)
    turn_c, turn_s = math.cos(2.0 * spread), math.sin(2.0 * spread)  # from one sector's axis to the next
    for k in range(rays):
        ux[k], uy[k] = c, s
        reach[k] = min(max_range, _wall_range(x, y, c, s, room_x, room_y, cos_s, sin_s))
        c, s = c * turn_c - s * turn_s, c * turn_s + s * turn_c
    if use_field:  # no obstacle within ``free`` of the robot
        _march_cones(field, x0, y0, x, y, ux, uy, widen, field_at(field, x0, y0, x, y) - HIT, reach)
    for k in range(rays):
        o[start + k] = reach[k] / max_range
