"""The way to the group through a furnished room: a geodesic distance map and the waypoint the policy steers to.

The Vector observation tells the policy where its place is (entries 0-1, the free slot), and the 3 m range scan
what is around it; a reactive policy steering for the slot drives into pockets of furniture that open toward the
group and waits there (most of the time-outs in the Willow Garage rooms, measured). So, in a room with obstacles,
entries 0-1 hold a **waypoint** whenever the straight way to the slot is not free (the footprint's circle would
touch an obstacle) and the robot is not yet near the way in: the point ``AHEAD`` metres along the shortest free
way, found by descending a geodesic distance map. Once the slot is in sight, or the robot is within
``WAY_IN_ZONE`` of the way in's circle, they hold the slot again, as they always do in an empty room.

* ``plan_map``: shortest ways (8 neighbours; a diagonal step costs 1.5 cells, so Dial's bucket queue replaces a
  heap) over the nodes of the room's distance field, from the way in
  (``entry_point``: the slot's ray just outside the group's keep-out disc, where spawning guarantees a way from
  the start, ``spawn.Approach``) over the nodes where the robot's circle keeps ``clearance`` from walls and
  obstacles and stays out of the group's disc: metres to the way in, inf where cut off. One per episode (the
  group stays where it stands; the slot moves by centimetres as it makes room).
* ``way_length``: the same distance from the way in to one point only (A*), for the furniture's detour.
* ``waypoint``: from the robot's cell, down the map for ``AHEAD`` metres.
* ``plan_distance``: the map read at any point (the reward's way round furniture, ``kernels.route_to_slot``).
* ``in_sight``: the straight way from the robot to the slot keeps ``clearance`` (the field, sampled every 5 cm).

The same functions run in the compiled step (``kernels.observations``) and in deploy (``deploy.frames``), on the
map's field. Ours (the paper's rooms were empty); docs/decisions.md "Waypoints in furnished rooms".
"""

from __future__ import annotations

import heapq
import math

import numpy as np
from numba import njit

from ...core.shield import ShieldParams
from .obstacles import CELL, field_at

PLAN_CELL = CELL  # the field's own nodes: passages that spawning found on them close on a coarser grid
AHEAD = 1.5  # m along the way: past a desk's corner, and the shield still brakes for what the scan sees
ENTRY_BEYOND = 2 * CELL  # m beyond the group's keep-out disc on the slot's ray: where the way in starts
SIGHT_STEP = 0.05  # m between samples of the straight way
WAY_IN_ZONE = 0.3  # m beyond the way in within which the slot is shown: the way in is free (spawning), the plan's
#                    goal behind the robot once it passed it


def way_clearances(reach: float) -> tuple[float, float]:
    """(plan, sight) clearances (m) from obstacles for a footprint of circumscribed radius ``reach``: the plan
    keeps the shield's margin (spawning guarantees a way with it), the straight way only the footprint's."""
    return reach + ShieldParams().obstacle_clearance_min, reach


def entry_point(cx: float, cy: float, sx: float, sy: float, keep_out: float) -> tuple[float, float]:
    """Where the way in to the slot (sx, sy) of the group centred at (cx, cy) starts: on the slot's ray,
    ``ENTRY_BEYOND`` outside the disc of ``keep_out``."""
    ux, uy = sx - cx, sy - cy
    norm = max(math.hypot(ux, uy), 1e-9)
    return cx + ux / norm * (keep_out + ENTRY_BEYOND), cy + uy / norm * (keep_out + ENTRY_BEYOND)


@njit(cache=True)
def _room_nodes(field: np.ndarray, room_x: float, room_y: float) -> tuple[int, int]:
    """(rows, columns) of the room's own nodes: a batch's field slots are sized for its largest room."""
    return (min(field.shape[0], int(math.ceil(room_y / PLAN_CELL)) + 1),
            min(field.shape[1], int(math.ceil(room_x / PLAN_CELL)) + 1))


@njit(cache=True)
def _free_node(field: np.ndarray, x0: float, y0: float, room_x: float, room_y: float, clearance: float,
               cx: float, cy: float, keep_out: float, i: int, j: int, obstacles: bool) -> bool:
    """Whether the robot's circle at node (i, j) keeps ``clearance`` from the walls and (``obstacles``) from what
    the field holds, and stays farther than ``keep_out`` from the group's centre (cx, cy)."""
    x, y = x0 + j * PLAN_CELL, y0 + i * PLAN_CELL
    return ((not obstacles or field[i, j] >= clearance) and abs(x) <= room_x / 2 - clearance
            and abs(y) <= room_y / 2 - clearance and math.hypot(x - cx, y - cy) > keep_out)


@njit(cache=True)
def _goal_node(field: np.ndarray, x0: float, y0: float, room_x: float, room_y: float, clearance: float,
               cx: float, cy: float, keep_out: float, wx: float, wy: float, obstacles: bool) -> tuple[int, int]:
    """The free node nearest the way in (wx, wy) within 0.5 m; (-1, -1) when none is."""
    ny, nx = _room_nodes(field, room_x, room_y)
    gi, gj, best = -1, -1, np.inf
    ci, cj = int(round((wy - y0) / PLAN_CELL)), int(round((wx - x0) / PLAN_CELL))
    r = int(math.ceil(0.5 / PLAN_CELL))
    for i in range(max(ci - r, 0), min(ci + r + 1, ny)):
        for j in range(max(cj - r, 0), min(cj + r + 1, nx)):
            d = math.hypot(x0 + j * PLAN_CELL - wx, y0 + i * PLAN_CELL - wy)
            if d < best and _free_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, i, j,
                                       obstacles):
                gi, gj, best = i, j, d
    return gi, gj


@njit(cache=True)
def plan_map(field: np.ndarray, x0: float, y0: float, room_x: float, room_y: float, clearance: float,
             cx: float, cy: float, keep_out: float, wx: float, wy: float, out: np.ndarray) -> bool:
    """Metres from every node of ``field`` to the way in (wx, wy) into ``out`` (the field's shape; inf: cut off),
    moving through nodes where the field (and the walls) keep ``clearance`` and farther than ``keep_out`` from
    the group's centre (cx, cy). False when no free node lies within 0.5 m of the way in."""
    out[:, :] = np.inf
    ny, nx = _room_nodes(field, room_x, room_y)
    free = np.zeros((ny, nx), dtype=np.bool_)
    for i in range(ny):
        for j in range(nx):
            free[i, j] = _free_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, i, j, True)
    gi, gj = _goal_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, wx, wy, True)
    if gi < 0:
        return False
    # Dial's algorithm: steps cost 2 (along a side) or 3 (diagonal) half-cells, so the queue is 4 buckets
    far = np.iinfo(np.int64).max
    dist = np.full(ny * nx, far, dtype=np.int64)
    buckets = np.empty((4, ny * nx), dtype=np.int64)
    counts = np.zeros(4, dtype=np.int64)
    dist[gi * nx + gj] = 0
    buckets[0, 0], counts[0], queued, cur = gi * nx + gj, 1, 1, 0
    while queued > 0:
        b = cur % 4
        while counts[b] > 0:
            counts[b] -= 1
            k = buckets[b, counts[b]]
            queued -= 1
            if dist[k] != cur:
                continue
            i, j = k // nx, k % nx
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    a, c = i + di, j + dj
                    if (di == 0 and dj == 0) or a < 0 or c < 0 or a >= ny or c >= nx or not free[a, c]:
                        continue
                    nd = cur + (3 if di != 0 and dj != 0 else 2)
                    m = a * nx + c
                    if nd < dist[m]:
                        dist[m] = nd
                        q = nd % 4
                        buckets[q, counts[q]] = m
                        counts[q] += 1
                        queued += 1
        cur += 1
    for i in range(ny):
        for j in range(nx):
            d = dist[i * nx + j]
            out[i, j] = np.inf if d == far else d * (0.5 * PLAN_CELL)
    return True


@njit(cache=True)
def _octile(di: int, dj: int) -> int:
    """The grid's own distance (half-cells: 2 a side step, 3 a diagonal one) between nodes di, dj apart."""
    a, b = abs(di), abs(dj)
    return 3 * min(a, b) + 2 * (max(a, b) - min(a, b))


@njit(cache=True)
def way_length(field: np.ndarray, x0: float, y0: float, room_x: float, room_y: float, clearance: float,
               cx: float, cy: float, keep_out: float, wx: float, wy: float, sx: float, sy: float,
               obstacles: bool) -> float:
    """``plan_map``'s distance (m) from the way in (wx, wy) to (sx, sy)'s node (to the nearest of its free
    neighbours when that node is not free), inf when cut off; ``obstacles`` False: through the empty room (walls
    and the group's disc only). The same ways on the same grid, searched from the way in toward the one point
    (A* with the grid's own distance as the estimate) instead of over the whole room: 5-10 x less work, what
    ``kernels.detour_steps`` needs at an episode's 30 s mark."""
    ny, nx = _room_nodes(field, room_x, room_y)
    gi, gj = _goal_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, wx, wy, obstacles)
    if gi < 0:
        return np.inf
    si = min(max(int(round((sy - y0) / PLAN_CELL)), 0), ny - 1)
    sj = min(max(int(round((sx - x0) / PLAN_CELL)), 0), nx - 1)
    exact = _free_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, si, sj, obstacles)
    slack = 0 if exact else 3  # a neighbour of the start's node is at most a diagonal step from it
    far = np.iinfo(np.int64).max
    dist = np.full(ny * nx, far, dtype=np.int64)
    known = np.zeros(ny * nx, dtype=np.int8)  # 0: not looked at, 1: free, 2: not free
    dist[gi * nx + gj] = 0
    heap = [(max(_octile(gi - si, gj - sj) - slack, 0), 0, gi * nx + gj)]
    best = far
    while len(heap) > 0:
        f, g, k = heapq.heappop(heap)
        if g != dist[k]:
            continue
        if f >= best:
            break
        i, j = k // nx, k % nx
        if (i == si and j == sj) if exact else (abs(i - si) <= 1 and abs(j - sj) <= 1):
            best = min(best, g)
            continue
        for di in range(-1, 2):
            for dj in range(-1, 2):
                a, c = i + di, j + dj
                if (di == 0 and dj == 0) or a < 0 or c < 0 or a >= ny or c >= nx:
                    continue
                m = a * nx + c
                nd = g + (3 if di != 0 and dj != 0 else 2)
                if nd >= dist[m]:
                    continue
                if known[m] == 0:
                    known[m] = 1 if _free_node(field, x0, y0, room_x, room_y, clearance, cx, cy, keep_out, a, c,
                                               obstacles) else 2
                if known[m] == 1:
                    dist[m] = nd
                    heapq.heappush(heap, (nd + max(_octile(a - si, c - sj) - slack, 0), nd, m))
    return np.inf if best == far else best * (0.5 * PLAN_CELL)


@njit(cache=True)
def waypoint(plan: np.ndarray, x0: float, y0: float, x: float, y: float) -> tuple[float, float, bool]:
    """The point ``AHEAD`` metres down ``plan`` from (x, y) (from the nearest reachable cell within 0.4 m when the
    robot's own is cut off); found false when none is reachable or the robot is at the way in already."""
    ny, nx = plan.shape
    i = min(max(int(round((y - y0) / PLAN_CELL)), 0), ny - 1)
    j = min(max(int(round((x - x0) / PLAN_CELL)), 0), nx - 1)
    if not math.isfinite(plan[i, j]):
        r = int(math.ceil(0.4 / PLAN_CELL))
        bi, bj, best = -1, -1, np.inf
        for a in range(max(i - r, 0), min(i + r + 1, ny)):
            for b in range(max(j - r, 0), min(j + r + 1, nx)):
                if plan[a, b] < best:
                    bi, bj, best = a, b, plan[a, b]
        if bi < 0:
            return x, y, False
        i, j = bi, bj
    gone = 0.0
    while gone < AHEAD - 0.5 * PLAN_CELL:
        bi, bj, best = i, j, plan[i, j]
        for a in range(max(i - 1, 0), min(i + 2, ny)):
            for b in range(max(j - 1, 0), min(j + 2, nx)):
                if plan[a, b] < best:
                    bi, bj, best = a, b, plan[a, b]
        if bi == i and bj == j:
            break
        gone += PLAN_CELL * (math.sqrt(2.0) if bi != i and bj != j else 1.0)
        i, j = bi, bj
    if plan[i, j] == 0.0 and math.hypot(x0 + j * PLAN_CELL - x, y0 + i * PLAN_CELL - y) < 0.5 * AHEAD:
        return x, y, False  # at the way in: the slot is the next place to go
    return x0 + j * PLAN_CELL, y0 + i * PLAN_CELL, True


NEAR_NODE = 0.3  # m: a point off the map (inside an obstacle's margin) reads the best node this near, plus the way


@njit(cache=True)
def plan_distance(plan: np.ndarray, x0: float, y0: float, x: float, y: float) -> float:
    """Metres from (x, y) to the way in along ``plan``: interpolated between the four nodes around the point when
    all are reachable, else the best reachable node within ``NEAR_NODE`` plus the straight way to it; inf when
    none is."""
    ny, nx = plan.shape
    u, v = (x - x0) / PLAN_CELL, (y - y0) / PLAN_CELL
    j, i = int(math.floor(u)), int(math.floor(v))
    if 0 <= i < ny - 1 and 0 <= j < nx - 1:
        a, b, c, d = plan[i, j], plan[i, j + 1], plan[i + 1, j], plan[i + 1, j + 1]
        if a < np.inf and b < np.inf and c < np.inf and d < np.inf:
            u, v = u - j, v - i
            return (a * (1.0 - u) + b * u) * (1.0 - v) + (c * (1.0 - u) + d * u) * v
    r = int(math.ceil(NEAR_NODE / PLAN_CELL))
    best = np.inf
    for a in range(max(i - r + 1, 0), min(i + r + 1, ny)):
        for b in range(max(j - r + 1, 0), min(j + r + 1, nx)):
            if plan[a, b] < np.inf:
                gap = math.hypot(x0 + b * PLAN_CELL - x, y0 + a * PLAN_CELL - y)
                if gap <= NEAR_NODE:
                    best = min(best, plan[a, b] + gap)
    return best


@njit(cache=True)
def in_sight(field: np.ndarray, x0: float, y0: float, x: float, y: float, sx: float, sy: float,
             clearance: float) -> bool:
    """Whether every point of the straight way from (x, y) to (sx, sy) keeps ``clearance`` from obstacles: marched
    through the field, each step as long as the room beyond ``clearance`` (at least ``SIGHT_STEP``)."""
    length = math.hypot(sx - x, sy - y)
    if length < 1e-9:
        return field_at(field, x0, y0, x, y) >= clearance
    ux, uy = (sx - x) / length, (sy - y) / length
    t = 0.0
    while True:
        room = field_at(field, x0, y0, x + ux * t, y + uy * t) - clearance
        if room < 0.0:
            return False
        if t >= length:
            return True
        t = min(t + max(room, SIGHT_STEP), length)


def way_in_for_group(members: np.ndarray, centre: np.ndarray, slot: np.ndarray, body_reach: float,
                     near_group: bool = False) -> tuple[float, float, float, float]:
    """(keep_out, way-in x, way-in y, show radius) for a group whose members stand at ``members`` (n, 2) around
    ``centre``: the keep-out disc spawning checks (``spawn.Approach``: the farthest member's distance from the
    centre plus ``body_reach``, the member's body radius + the footprint's reach + the intimate zone), the way in
    (``entry_point``) and the radius around the centre beyond which the plan shows the way (up to
    ``WAY_IN_ZONE`` beyond the way in; ``near_group``: right up to the keep-out disc, where a group whose near
    side is shut by furniture is gone round by its far side). Used by the env at each episode's start and by
    deploy."""
    ring = float(np.hypot(members[:, 0] - centre[0], members[:, 1] - centre[1]).max()) if len(members) else 0.0
    keep_out = ring + body_reach
    wx, wy = entry_point(float(centre[0]), float(centre[1]), float(slot[0]), float(slot[1]), keep_out)
    return keep_out, wx, wy, keep_out if near_group else keep_out + ENTRY_BEYOND + WAY_IN_ZONE
