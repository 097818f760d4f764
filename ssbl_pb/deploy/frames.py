"""Where the robot is: odometry frame -> room frame (the policy's walls) -> map frame (the log's paths).

With ``--map room.yaml --start-pose X Y YAW`` (``tools/import_map.py``'s room YAML; the start pose in the map
frame, read off the map) the room frame is the room's, so the policy sees the real walls, and paths are drawn on
the occupancy map. Without a map the room frame is the odometry frame and the walls are reported 5 m away on
every side: the middle of the training room (10 m), a place the policy knows, with no wall near.

The range scan of the observation is cast from the localised pose against the room's walls and the room YAML's
obstacles (``scan``), with the simulator's own function (``env.rooms.obstacles.fill_scan``): what the policy saw in
training, people excluded (Pepper's lasers would see the members' legs, which the observation carries apart, and
leave the rear 120 deg blind). Without a map, or with a room YAML without obstacles, nothing is known: every ray
reports its full range, as in the middle of an empty training room.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..calib.room_map import OccupancyMap, read_map
from ..core import observation as ob
from ..env.rooms.obstacles import box_rows, fill_scan
from ..env.rooms.planner import in_sight, plan_map, way_clearances, way_in_for_group, waypoint
from ..env.rooms.rooms import Room, read_obstacles
from ..errors import UserError
from ..params import WorldParams, load_yaml
from .robot import compose, relative

NO_WALLS = 5.0  # m to each wall without a map: half the default room (WorldParams.room_size)


def transform_points(frame: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Points (n, 2) given in ``frame`` (a pose x, y, yaw) -> the frame that pose is expressed in."""
    c, s = math.cos(frame[2]), math.sin(frame[2])
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return xy @ np.array([[c, s], [-s, c]]) + np.asarray(frame[:2], dtype=float)


def inverse(pose: np.ndarray) -> np.ndarray:
    return relative(np.asarray(pose, dtype=float), np.zeros(3))


@dataclasses.dataclass
class RoomMap:
    """A room YAML: the room's size, the map <- room transform and the occupancy map it was cut from."""

    path: Path
    room_size: tuple[float, float]
    map_to_room: np.ndarray  # pose of the room frame in the map frame
    grid: OccupancyMap
    obstacles: Room | None = None  # the room YAML's obstacles (``obstacles.boxes``), None without them


def load_room(path: str | Path) -> RoomMap:
    """Read ``tools/import_map.py``'s room YAML and its map; ``UserError`` naming the file and field."""
    path = Path(path)
    try:
        data = load_yaml(path)
    except UserError as exc:
        raise UserError(f"--map {exc}") from None
    for key in ("world", "map", "map_to_room"):
        if not isinstance(data.get(key), dict):
            raise UserError(f"--map {path}: no '{key}:' mapping; expected a room YAML from tools/import_map.py")
    size = data["world"].get("room_size", WorldParams.room_size)
    try:
        world = WorldParams(room_size=tuple(float(v) for v in size))
        t = data["map_to_room"]
        pose = np.array([float(t["x"]), float(t["y"]), float(t["yaw"])])
    except (TypeError, ValueError, KeyError) as exc:
        raise UserError(f"--map {path}: bad room_size or map_to_room ({exc})") from None
    map_yaml = Path(str(data["map"].get("yaml", "")))
    if not map_yaml.is_absolute() and not map_yaml.is_file():
        map_yaml = path.parent / map_yaml
    try:
        grid = read_map(map_yaml)
        boxes = read_obstacles(path, data)
    except UserError as exc:
        raise UserError(f"--map {path}: its map does not load ({exc})") from None
    room = None if boxes is None or not len(boxes) else Room(world.room_size, box_rows(boxes), str(path))
    return RoomMap(path, world.room_size, pose, grid, room)


class Frames:
    """Odometry -> room -> map, fixed at the first odometry reading (``anchor``)."""

    def __init__(self, room: RoomMap | None = None, start_map: np.ndarray | None = None) -> None:
        self.room = room
        self.start_map = None if start_map is None else np.asarray(start_map, dtype=float)
        self._plan: np.ndarray | None = None  # ``way_to``'s plan, for the group and slot in ``_plan_key``
        self._plan_key: np.ndarray | None = None
        self._plan_radius = 0.0
        self.room_from_odom: np.ndarray | None = None  # pose of the odometry frame in the room frame

    def check_start(self) -> None:
        """The start pose must lie on a free cell of the map (before anything moves)."""
        if self.room is None:
            return
        if self.start_map is None:
            raise UserError("--map needs --start-pose X Y YAW (the robot's pose on the map, metres and degrees)")
        grid = self.room.grid
        col, row = (int(v) for v in np.floor(grid.map_to_pixel(self.start_map[:2])[0] + 0.5))
        h, w = grid.shape
        if not (0 <= row < h and 0 <= col < w):
            raise UserError(f"--start-pose {self.start_map[0]:g} {self.start_map[1]:g}: outside the map "
                            f"{grid.yaml_path}")
        if grid.grid[row, col] != 0:
            state = {1: "occupied", -1: "unknown"}[int(grid.grid[row, col])]
            raise UserError(f"--start-pose {self.start_map[0]:g} {self.start_map[1]:g}: an {state} cell of the map "
                            f"{grid.yaml_path}; expected free space")

    def anchor(self, odom_pose: np.ndarray) -> None:
        if self.room_from_odom is not None:
            return
        if self.room is None:
            self.room_from_odom = np.zeros(3)
            return
        start_room = relative(self.room.map_to_room, self.start_map)
        self.room_from_odom = compose(start_room, inverse(odom_pose))

    def room_pose(self, odom_pose: np.ndarray) -> np.ndarray:
        return compose(self.room_from_odom, odom_pose)

    def room_points(self, xy: np.ndarray) -> np.ndarray:
        return transform_points(self.room_from_odom, xy)

    def map_pose(self, odom_pose: np.ndarray) -> np.ndarray | None:
        return None if self.room is None else compose(self.room.map_to_room, self.room_pose(odom_pose))

    def walls(self, room_pose: np.ndarray) -> np.ndarray:
        """Distances to the walls (+x, -x, +y, -y) as ``env.gymenv.approach`` computes them."""
        if self.room is None:
            return np.full(4, NO_WALLS)
        (sx, sy), (x, y) = self.room.room_size, room_pose[:2]
        return np.array([sx / 2 - x, x + sx / 2, sy / 2 - y, y + sy / 2])

    def scan(self, room_pose: np.ndarray, frame_yaw: float) -> np.ndarray:
        """The observation's range scan (``observation.SCAN_RAYS`` entries, divided by the range) from the robot
        at ``room_pose``, ray 0 along ``frame_yaw`` (both in the room frame)."""
        out = np.ones(ob.SCAN_RAYS, dtype=np.float32)
        if self.room is None:
            return out
        obstacles = self.room.obstacles
        field = obstacles.field if obstacles is not None else np.zeros((1, 1), dtype=np.float32)
        x0, y0 = (obstacles.x0, obstacles.y0) if obstacles is not None else (0.0, 0.0)
        fill_scan(out, 0, ob.SCAN_RAYS, obstacles is not None, field, x0, y0, float(room_pose[0]),
                  float(room_pose[1]), float(frame_yaw), ob.SCAN_RANGE, *self.room.room_size)
        return out

    def way_to(self, room_pose: np.ndarray, members: np.ndarray, centre: np.ndarray, slot: np.ndarray, reach: float,
               body_reach: float, near_group: bool = False) -> np.ndarray:
        """What the observation's slot entries show for a policy trained with waypoints (``env.rooms.planner``, room
        frame): the slot, or the point along the way around the map's obstacles while the slot is out of sight.
        The plan is made again when the group's centre or slot estimate moved 0.2 m (~1 ms); ``near_group`` as
        the policy was trained (``planner.way_in_for_group``)."""
        obstacles = None if self.room is None else self.room.obstacles
        if obstacles is None:
            return slot
        key = np.concatenate([centre, slot])
        if self._plan_key is None or float(np.abs(key - self._plan_key).max()) > 0.2:
            if self._plan is None:
                self._plan = np.empty_like(obstacles.field)
            keep_out, wx, wy, radius = way_in_for_group(members, centre, slot, body_reach, near_group)
            made = plan_map(obstacles.field, obstacles.x0, obstacles.y0, *self.room.room_size,
                            way_clearances(reach)[0], float(centre[0]), float(centre[1]), keep_out, wx, wy,
                            self._plan)
            self._plan_radius, self._plan_key = (radius if made else 0.0), key
        x, y = float(room_pose[0]), float(room_pose[1])
        if (self._plan_radius <= 0 or math.hypot(x - centre[0], y - centre[1]) <= self._plan_radius
                or in_sight(obstacles.field, obstacles.x0, obstacles.y0, x, y, float(slot[0]), float(slot[1]),
                            way_clearances(reach)[1])):
            return slot
        wx, wy, found = waypoint(self._plan, obstacles.x0, obstacles.y0, x, y)
        return np.array([wx, wy]) if found else slot

    def info(self) -> dict[str, Any]:
        return {"map": None if self.room is None else str(self.room.path),
                "start_pose_map": None if self.start_map is None else self.start_map.tolist(),
                "room_from_odom": None if self.room_from_odom is None else self.room_from_odom.tolist()}
