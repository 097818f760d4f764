"""Where an episode starts: the group's centre and layout and the robot's pose, in an empty or furnished room.

In an empty room the group keeps ``wall_margin`` from the walls even once the robot has joined, and the robot
starts ``robot_spawn_min``..``robot_spawn_max`` from its centre (anywhere around it, or behind a member). In a
room with obstacles the group also stands clear of them with room for the robot at its place, and the robot
starts clear of every obstacle at a place from which it can drive to the group (``Approach``). Empty rooms draw
exactly the random numbers they drew before obstacles existed, so their episodes are unchanged.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...core.humans import MAX_HUMANS, free_slot
from ...core.layouts import GroupModel, Layout, member_keep_out, slot_keep
from ...core.shield import ShieldParams
from ...core.task import TaskParams
from ...params import ConfigError, RobotParams, SocialParams, WorldParams
from .obstacles import CELL, boxes_distance, field_at
from .planner import ENTRY_BEYOND
from .rooms import Room

ROBOT_TRIES = 20  # robot starts tried per group centre in a room with obstacles
# m the footprint's reach keeps from obstacles at the start and on its way to the group: the safety shield's
# margin (``ShieldParams.obstacle_clearance_min``), so the way is one the shielded robot can drive through
START_CLEARANCE = ShieldParams().obstacle_clearance_min
GROUP_CLEARANCE = 0.2  # m beyond the members' bodies and the robot at its place kept free of obstacles (a step)


class NoPlace(ConfigError):
    """No place for the group and the robot was found in the room."""


def spawn_layout(rng: np.random.Generator, world: WorldParams, robot: RobotParams, social: SocialParams, n: int,
                 formation: str, start: str = "any", groups: GroupModel | None = None, room: Room | None = None,
                 keep: float = 0.0, task: TaskParams | None = None) -> tuple[np.ndarray, Layout, np.ndarray]:
    """A group's centre (2,) and layout (``layouts.Layout``) and the robot's pose (x, y, yaw) for one episode in
    ``room`` (default: the empty ``world.room_size``); ``keep`` as ``humans.Group``'s; ``task``: the task whose
    intimate zone the way in keeps out of (default ``TaskParams()``). ``NoPlace`` when 1000 group places fail.
    With obstacles, ``Approach.fits`` must also hold."""
    if not isinstance(n, int | np.integer) or not 2 <= n <= MAX_HUMANS:
        raise ConfigError(f"n_humans = {n!r}: expected an integer in [2, {MAX_HUMANS}]")
    if start not in ("any", "behind"):
        raise ConfigError(f"start = {start!r}: expected 'any' or 'behind'")
    sx, sy = world.room_size if room is None else room.size
    furnished = room is not None and room.furnished
    layout = (groups or GroupModel()).layout(formation, int(n), social, rng)
    extent = max(layout.joined_radius, float(np.hypot(layout.offsets[:, 0], layout.offsets[:, 1]).max()))
    margin = extent + social.human_radius + world.wall_margin
    robot_margin = robot.length / 2 + world.wall_margin
    angles = np.arctan2(layout.offsets[:, 1], layout.offsets[:, 0])
    intimate_zone = (task or TaskParams()).intimate_zone
    approach = Approach(layout, social, robot, keep, room, intimate_zone) if furnished else None
    where = f"the room {room.source}" if room is not None else f"world.room_size = {world.room_size}"
    if 2 * margin > min(sx, sy):  # a small furnished room and a wide real group: draw another room
        raise NoPlace(f"{where}: {min(sx, sy)} m across is too small for a group of {n} ({formation}) that needs "
                      f"{2 * margin:.2f} m")
    for _ in range(1000):
        centre = np.array([rng.uniform(-sx / 2 + margin, sx / 2 - margin),
                           rng.uniform(-sy / 2 + margin, sy / 2 - margin)])
        if approach is not None and boxes_distance(centre[0], centre[1], room.rows) < approach.members:
            continue
        for _ in range(ROBOT_TRIES if furnished else 1):
            if start == "behind":
                k = int(rng.integers(n))
                theta = angles[k] + rng.uniform(-0.3, 0.3)
            else:
                theta = rng.uniform(0, 2 * math.pi)
            dist = rng.uniform(world.robot_spawn_min, world.robot_spawn_max)
            xy = centre + dist * np.array([math.cos(theta), math.sin(theta)])
            inside = abs(xy[0]) <= sx / 2 - robot_margin and abs(xy[1]) <= sy / 2 - robot_margin
            if inside and (approach is None or approach.fits(centre, xy)):
                return centre, layout, np.array([xy[0], xy[1], rng.uniform(-math.pi, math.pi)])
    raise NoPlace(f"{where}: no place for a group of {n} ({formation}) and the robot after 1000 tries (the group "
                  f"needs free space around it and its joining place, and the robot a start {world.robot_spawn_min}-"
                  f"{world.robot_spawn_max} m away from which it can drive there)")


class Approach:
    """Whether a group of ``layout`` at some centre and a robot starting at some place fit a room with obstacles:
    the members' bodies keep ``GROUP_CLEARANCE`` from every obstacle (``members``: the free radius they need); the
    robot at its place (the slot at rest, toward the robot) and on the way in along the slot's ray keeps its
    footprint's reach plus ``GROUP_CLEARANCE`` from obstacles and walls; the robot's start keeps its reach plus
    ``START_CLEARANCE``, and a path keeping that clearance leads from the start to where that way in begins, around
    the group (its keep-out disc: the members' bodies plus the footprint's reach and the task's
    ``intimate_zone``, as the shaping's route keeps, ``reward.route_length``)."""

    def __init__(self, layout: Layout, social: SocialParams, robot: RobotParams, keep: float, room: Room,
                 intimate_zone: float) -> None:
        self.offsets, self.room, self.reach = layout.offsets, room, robot.reach
        ring = np.hypot(self.offsets[:, 0], self.offsets[:, 1])
        self.members = float(ring.max()) + social.human_radius + GROUP_CLEARANCE
        self.radius, self.keep = layout.radius, 0.0 if layout.paper else keep
        self.joined = layout.joined_radius
        self.keep_out = float(ring.max()) + member_keep_out(social, robot.reach, intimate_zone)

    def fits(self, centre: np.ndarray, xy: np.ndarray) -> bool:
        room = self.room
        return _fits(room.field, room.x0, room.y0, room.size[0], room.size[1], self.offsets, float(centre[0]),
                     float(centre[1]), self.radius, self.keep, float(xy[0]), float(xy[1]), self.reach, self.joined,
                     self.keep_out)


@njit(cache=True)
def _clearance(field: np.ndarray, x0: float, y0: float, size_x: float, size_y: float, x: float, y: float) -> float:
    """Distance (m) from a point to the nearest obstacle or wall (the field's cap at most)."""
    return min(size_x / 2 - abs(x), size_y / 2 - abs(y), field_at(field, x0, y0, x, y))


@njit(cache=True)
def _fits(field: np.ndarray, x0: float, y0: float, size_x: float, size_y: float, offsets: np.ndarray, cx: float,
          cy: float, radius: float, keep: float, rx: float, ry: float, reach: float, joined: float,
          keep_out: float) -> bool:
    """``Approach.fits`` for the group centred at (cx, cy) and the robot starting at (rx, ry)."""
    if _clearance(field, x0, y0, size_x, size_y, rx, ry) < reach + START_CLEARANCE:
        return False
    n = offsets.shape[0]
    pos = np.empty((n, 2))
    for j in range(n):
        pos[j, 0], pos[j, 1] = cx + offsets[j, 0], cy + offsets[j, 1]
    sx, sy = free_slot(n, pos, cx, cy, radius, keep, rx, ry, True)
    norm = math.hypot(sx - cx, sy - cy)
    place = max(norm, joined)
    ux, uy = (sx - cx) / max(norm, 1e-9), (sy - cy) / max(norm, 1e-9)
    # the way in along the slot's ray, every 0.1 m from the place out past the keep-out disc (numpy's arange)
    stop, delta = keep_out + ENTRY_BEYOND + 1e-9, (place + 0.1) - place
    for k in range(max(int(math.ceil((stop - place) / 0.1)), 0)):
        d = place + k * delta
        if _clearance(field, x0, y0, size_x, size_y, cx + d * ux, cy + d * uy) < reach + GROUP_CLEARANCE:
            return False
    # where the way in starts (``planner.entry_point``), reached around the group
    ex, ey = cx + ux * (keep_out + ENTRY_BEYOND), cy + uy * (keep_out + ENTRY_BEYOND)
    clearance = reach + START_CLEARANCE
    return _connected(field, x0, y0, size_x, size_y, clearance, cx, cy, keep_out, int(round((ry - y0) / CELL)),
                      int(round((rx - x0) / CELL)), int(round((ey - y0) / CELL)), int(round((ex - x0) / CELL)))


@njit(cache=True)
def _connected(field: np.ndarray, x0: float, y0: float, size_x: float, size_y: float, clearance: float,
               cx: float, cy: float, keep_out: float, ia: int, ja: int, ib: int, jb: int) -> bool:
    """Whether a path over the field's nodes leads from (ia, ja) to (ib, jb) through nodes at least ``clearance``
    from obstacles and walls and farther than ``keep_out`` from (cx, cy); stops when it arrives (a reset checks
    one start, so a search that ends early beats labelling the whole room)."""
    ny, nx = field.shape

    def free(i: int, j: int) -> bool:
        if i < 0 or j < 0 or i >= ny or j >= nx or field[i, j] < clearance:
            return False
        x, y = x0 + j * CELL, y0 + i * CELL
        return (abs(x) <= size_x / 2 - clearance and abs(y) <= size_y / 2 - clearance
                and (x - cx) ** 2 + (y - cy) ** 2 > keep_out ** 2)

    if not free(ia, ja) or not free(ib, jb):
        return False
    # the straight way first: free by two more cells all along it, the staircase of nodes beside it (within a
    # cell's diagonal) is free too (distances change by at most that over it), so the search would arrive; most
    # starts see their way in, and this costs ~1 % of the search
    steps = max(abs(ib - ia), abs(jb - ja), 1)
    straight = True
    for k in range(steps + 1):
        t = k / steps
        y, x = y0 + (ia + (ib - ia) * t) * CELL, x0 + (ja + (jb - ja) * t) * CELL
        margin = clearance + 2 * CELL
        if (field_at(field, x0, y0, x, y) < margin or abs(x) > size_x / 2 - margin or abs(y) > size_y / 2 - margin
                or math.hypot(x - cx, y - cy) < keep_out + 2 * CELL):
            straight = False
            break
    if straight:
        return True
    # greedy best-first search: nodes in buckets by their Manhattan distance to (ib, jb), nearest first (the
    # breadth-first search it replaced visited most of the room when the group stood in the way; the answer, a
    # path or none, is the same for any search that visits every reachable node before giving up)
    seen = np.zeros((ny, nx), dtype=np.bool_)
    top = np.full(ny + nx, -1, dtype=np.int64)  # per distance, the last node pushed (a stack) ...
    below = np.empty(ny * nx, dtype=np.int64)  # ... and per node, the node pushed before it in its bucket
    lo = abs(ia - ib) + abs(ja - jb)
    top[lo], below[ia * nx + ja], seen[ia, ja] = ia * nx + ja, -1, True
    while lo < ny + nx:
        k = top[lo]
        if k < 0:
            lo += 1
            continue
        top[lo] = below[k]
        i, j = k // nx, k % nx
        if i == ib and j == jb:
            return True
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            u, v = i + di, j + dj
            if free(u, v) and not seen[u, v]:
                seen[u, v] = True
                d = abs(u - ib) + abs(v - jb)
                below[u * nx + v], top[d] = top[d], u * nx + v
                lo = min(lo, d)
    return False


def fitting_sizes(room: Room, world: WorldParams | None = None, robot: RobotParams | None = None,
                  social: SocialParams | None = None, tries: int = 3, task: TaskParams | None = None) -> list[int]:
    """Group sizes (2-5, calibrated vis-a-vis groups) for which ``spawn_layout`` finds a place in ``room`` (with the
    given parameters, default ones where None; ``tries`` seeded attempts each), for telling a user what a room
    holds."""
    world, robot, social = world or WorldParams(), robot or RobotParams(), social or SocialParams()
    task = task or TaskParams()
    keep = slot_keep(social, robot.reach, task.intimate_zone, task.route_margin)
    out = []
    for n in range(2, MAX_HUMANS + 1):
        for seed in range(tries):
            try:
                spawn_layout(np.random.default_rng(seed), world, robot, social, n, "vis_a_vis", room=room, keep=keep,
                             task=task)
            except NoPlace:
                continue
            out.append(n)
            break
    return out
