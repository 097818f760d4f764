"""The PyBullet scene: room, Pepper, a conversation group, collisions and cameras (headless DIRECT mode).

Motion is kinematic: the base (``base.HolonomicBase``) and the members (``humans.Group``) are integrated by the
compiled formulas at the control period, and their poses are pushed to PyBullet only when PyBullet is asked
something (rendering, contact queries), so PyBullet remains the scene and the renderer. The world owns its state,
or shows a batch's (``attach``: the env's state lives in ``batched.BatchedApproach``). Collisions are computed
exactly in the plane (Pepper's box footprint against the members' 0.28 m circles and the walls' inner faces), and
against the room's obstacles through their distance field (``obstacles``; the scene is rebuilt when the episode's
room changes, ``set_room``); ``pybullet_contacts`` cross-checks them with PyBullet's own geometry.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.base import BaseArrays, HolonomicBase, footprint_distance, wall_clearance
from ...core.humans import MAX_HUMANS, Group, GroupArrays
from ...core.layouts import GroupModel
from ...params import RobotParams, SocialParams, WorldParams
from ...urdf import HUMAN_COLOURS, urdf_path
from ..rooms.obstacles import footprint_clearance
from ..rooms.rooms import Room
from ..rooms.spawn import spawn_layout
from . import cameras
from .bodies import PARKED, body_count, body_order, load_body, park
from .bullet import pybullet as p

_PARKED = PARKED
OBSTACLE_HEIGHT = 0.75  # m: a desk's or a table's height (the camera at 1.15 m sees over it, as a person does)
OBSTACLE_COLOUR = [0.45, 0.33, 0.22, 1]  # wood brown: apart from the walls' grey and the members' colours


@dataclasses.dataclass
class Collision:
    """One contact: ``kind`` is "human" (``index`` = member), "wall" (``index`` 0..3 = +x, -x, +y, -y) or "obstacle"
    (``index`` 0)."""

    kind: str
    index: int


def box_circle_distance(pose: np.ndarray, half: tuple[float, float], centres: np.ndarray) -> np.ndarray:
    """Distance (m) from points (k, 2) to a box footprint with half-extents ``half`` at ``pose`` (0 inside)."""
    x, y, yaw = (float(v) for v in pose[:3])
    return np.array([footprint_distance(px - x, py - y, yaw, half[0], half[1])[0]
                     for px, py in np.asarray(centres, dtype=float).reshape(-1, 2).tolist()])


class World:
    """Pepper and one conversation group in a walled room; ``reset`` spawns, ``step`` advances by ``dt``."""

    def __init__(self, world: WorldParams | None = None, robot: RobotParams | None = None,
                 social: SocialParams | None = None, groups: GroupModel | None = None, keep: float = 0.0,
                 room: Room | None = None) -> None:
        """``groups``: where members stand (``layouts.GroupModel``, calibrated by default); ``keep``: the distance
        the robot's place keeps from every member's centre (``Group``, ``layouts.slot_keep``); ``room``: the room
        to show (``set_room``; a room given here was checked by its owner, an env: the empty room of ``world``
        must hold the group otherwise)."""
        self.params = world or WorldParams()
        self.robot_params = robot or RobotParams()
        self.social = social or SocialParams()
        self.groups = groups or GroupModel()
        self.keep = keep
        if room is None:
            self.params.check_fits(self.social)
        self.base = HolonomicBase(self.robot_params, self.params.dt)
        self.group: Group | None = None
        self._room: Room | None = room
        self._attached = False
        self.client = p.connect(p.DIRECT)
        self.t = 0.0
        self._synced = False
        try:
            self._build_scene()
        except Exception:
            p.disconnect(self.client)
            raise

    # -- scene --------------------------------------------------------------------------------------------
    def _build_scene(self) -> None:
        c = self.client
        self._static_ids: list[int] = []
        self.floor_id, self.wall_ids, self.obstacle_ids = -1, [], []
        self._built_room: Room | None = None
        self._build_room()
        self.robot_id = p.loadURDF(str(urdf_path("pepper")), [0, 0, 0], useFixedBase=True,
                                   flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=c)
        self.human_ids = []
        self.body_seed = 0
        self._bodies: list[int] = []
        if self.params.humans.appearance == "body":  # every body loaded once, parked; members take them by seed
            self._bodies = [load_body(c, k) for k in range(body_count())]
            self.human_ids = self._chosen_bodies()
            return
        for i in range(MAX_HUMANS):
            hid = p.loadURDF(str(urdf_path("human")), _PARKED, useFixedBase=True, physicsClientId=c)
            for link in (0, 1):  # torso and facing marker keep their own colours; recolour the torso only
                if link == 0:
                    p.changeVisualShape(hid, link, rgbaColor=HUMAN_COLOURS[i], physicsClientId=c)
            self.human_ids.append(hid)

    def _chosen_bodies(self) -> list[int]:
        order = body_order(self.body_seed)
        return [self._bodies[order[i % len(order)]] for i in range(MAX_HUMANS)]

    def set_body_seed(self, seed: int) -> None:
        """Members wear the bodies ``bodies.body_order(seed)`` gives (member i its entry i; ``humans.appearance:
        body``; the proxies ignore it)."""
        self.body_seed = int(seed)
        if self._bodies:
            for body in self.human_ids:
                park(self.client, body)
            self.human_ids = self._chosen_bodies()
            self._synced = False

    def _box(self, half: list[float], pos: list[float], yaw: float, rgba: list[float]) -> int:
        c = self.client
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=c)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=rgba, physicsClientId=c)
        body = p.createMultiBody(0, col, vis, pos, [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)], physicsClientId=c)
        self._static_ids.append(body)
        return body

    def _build_room(self) -> None:
        """(Re)build the floor, the walls and the obstacles of ``room`` (the room of this episode)."""
        for body in self._static_ids:
            p.removeBody(body, physicsClientId=self.client)
        self._static_ids = []
        room = self.room
        sx, sy = room.size
        th, h = self.params.wall_thickness, self.params.wall_height
        self.floor_id = self._box([sx / 2 + th, sy / 2 + th, 0.05], [0, 0, -0.05], 0.0, [0.78, 0.76, 0.72, 1])
        self.wall_ids = []
        for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):  # +x, -x, +y, -y
            half = [th / 2, sy / 2 + th, h / 2] if axis == 0 else [sx / 2 + th, th / 2, h / 2]
            pos = [0.0, 0.0, h / 2]
            pos[axis] = sign * ((sx if axis == 0 else sy) / 2 + th / 2)
            self.wall_ids.append(self._box(half, pos, 0.0, [0.55, 0.55, 0.6, 1]))
        self.obstacle_ids = [self._box([bx / 2, by / 2, OBSTACLE_HEIGHT / 2], [x, y, OBSTACLE_HEIGHT / 2], yaw,
                                       OBSTACLE_COLOUR) for x, y, bx, by, yaw in room.boxes().tolist()]
        self._built_room = room

    @property
    def room(self) -> Room:
        """The room of this episode (``set_room``; by default the empty room of ``WorldParams.room_size``)."""
        if self._room is None:
            self._room = Room(self.params.room_size)
        return self._room

    def set_room(self, room: Room | None) -> None:
        """Use ``room`` (None: the empty room of ``WorldParams.room_size``) from now on; PyBullet's scene follows at
        the next query."""
        self._room = room
        self._synced = False

    def close(self) -> None:
        """Disconnect from PyBullet (idempotent)."""
        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    # -- spawning -----------------------------------------------------------------------------------------
    def attach(self, bases: BaseArrays, groups: GroupArrays, i: int) -> None:
        """Show row ``i`` of a batch's state instead of owning one (``base`` and ``group`` become views; the
        batch steps it: call ``invalidate`` after each change)."""
        self.base = HolonomicBase(self.robot_params, self.params.dt, bases, i)
        self.group = Group(self.social, dt=self.params.dt, arrays=groups, i=i)
        self._attached = True
        self._synced = False

    def invalidate(self) -> None:
        """The state changed outside ``step`` (an attached batch stepped): sync PyBullet before the next query."""
        self._synced = False

    def reset(self, rng: np.random.Generator, n_humans: int | None = None, formation: str | None = None,
              start: str = "any") -> None:
        """Spawn a group (F-formation at a random place and rotation) and the robot outside it."""
        n = self.params.n_humans if n_humans is None else n_humans
        form = self.params.formation if formation is None else formation
        centre, layout, pose = spawn_layout(rng, self.params, self.robot_params, self.social, n, form, start,
                                            self.groups, self.room, self.keep)
        self.base.reset(pose)
        if self._attached:
            self.group.arrays.spawn(self.group.i, self.social, centre, layout, self.keep, pose[:2])
        else:
            self.group = Group(self.social, centre, layout, self.keep, self.params.dt)
            self.group.update_centre(pose[:2])
        self.t = 0.0
        self._synced = False

    # -- stepping -----------------------------------------------------------------------------------------
    def step(self, cmd: np.ndarray) -> np.ndarray:
        """Advance one control period with a body-frame base command; returns the accepted command."""
        if self.group is None:
            raise RuntimeError("World.step called before reset")
        accepted = self.base.step(cmd)
        self.group.step(self.base.pose[:2], self.params.dt)
        self.t += self.params.dt
        self._synced = False
        return accepted

    @property
    def robot_pose(self) -> np.ndarray:
        return self.base.pose

    def human_clearance(self) -> np.ndarray:
        """Gap (m) between Pepper's footprint and each member's body circle (negative when overlapping)."""
        assert self.group is not None
        half = (self.robot_params.length / 2, self.robot_params.width / 2)
        return box_circle_distance(self.base.pose, half, self.group.pos) - self.social.human_radius

    def wall_clearance(self) -> np.ndarray:
        """Distance (m) from the footprint's nearest corner to each wall's inner face (+x, -x, +y, -y)."""
        x, y, yaw = (float(v) for v in self.base.pose)
        return np.array(wall_clearance(x, y, yaw, self.robot_params.length / 2, self.robot_params.width / 2,
                                       *self.room.size))

    def obstacle_clearance(self) -> float:
        """Gap (m) between the footprint and the nearest obstacle (``obstacles.footprint_clearance``; at most its
        ``CAP``, inf in a room without obstacles)."""
        room = self.room
        if not room.furnished:
            return math.inf
        x, y, yaw = (float(v) for v in self.base.pose)
        return float(footprint_clearance(room.field, room.x0, room.y0, x, y, yaw, self.robot_params.length / 2,
                                         self.robot_params.width / 2))

    def in_contact(self, clearance: np.ndarray | None = None) -> bool:
        """Whether ``collisions`` would list anything (cheaper; ``clearance`` as there)."""
        return bool(self.collisions(clearance))

    def collisions(self, clearance: np.ndarray | None = None) -> list[Collision]:
        """Robot-human, robot-wall and robot-obstacle contacts right now (``clearance``: a ``human_clearance()``
        already made); an obstacle contact has index 0."""
        clearance = self.human_clearance() if clearance is None else clearance
        out = [Collision("human", int(i)) for i in np.flatnonzero(clearance <= 0.0)]
        out += [Collision("wall", int(i)) for i in np.flatnonzero(self.wall_clearance() <= 0.0)]
        if self.obstacle_clearance() <= 0.0:
            out.append(Collision("obstacle", 0))
        return out

    # -- PyBullet side ------------------------------------------------------------------------------------
    def sync(self) -> None:
        """Push the current poses into PyBullet (done lazily before any render or contact query)."""
        if self._synced:
            return
        if self._built_room is not self.room:
            self._build_room()
        c = self.client
        x, y, yaw = self.base.pose
        p.resetBasePositionAndOrientation(self.robot_id, [x, y, 0.0], [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)],
                                          physicsClientId=c)
        n = self.group.n if self.group is not None else 0
        for i, hid in enumerate(self.human_ids):
            if i < n:
                hx, hy = self.group.pos[i]
                hyaw = self.group.yaw[i]
                p.resetBasePositionAndOrientation(hid, [hx, hy, 0.0],
                                                  [0, 0, math.sin(hyaw / 2), math.cos(hyaw / 2)],
                                                  physicsClientId=c)
            else:
                p.resetBasePositionAndOrientation(hid, _PARKED, [0, 0, 0, 1], physicsClientId=c)
        self._synced = True

    def pybullet_contacts(self, distance: float = 0.0) -> list[Collision]:
        """Contacts as PyBullet's own collision shapes see them (slow; for cross-checks)."""
        self.sync()
        c = self.client
        out = []
        n = self.group.n if self.group is not None else 0
        for i in range(n):
            if p.getClosestPoints(self.robot_id, self.human_ids[i], distance, linkIndexA=-1, physicsClientId=c):
                out.append(Collision("human", i))
        for i, wid in enumerate(self.wall_ids):
            if p.getClosestPoints(self.robot_id, wid, distance, linkIndexA=-1, physicsClientId=c):
                out.append(Collision("wall", i))
        if any(p.getClosestPoints(self.robot_id, b, distance, linkIndexA=-1, physicsClientId=c)
               for b in self.obstacle_ids):
            out.append(Collision("obstacle", 0))
        return out

    def render_first_person(self, width: int = 84, height: int = 84, projection: list[float] | None = None,
                            segmentation: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Pepper's CameraTop image (H, W, 3) uint8, optionally with the segmentation mask."""
        self.sync()
        proj = projection or cameras.perspective(self.robot_params.camera_hfov_deg, width, height)
        view = cameras.first_person_view(self.base.pose, self.robot_params)
        return cameras.render(self.client, width, height, view, proj, segmentation)

    def top_down_camera(self, width: int = 480, centre: tuple[float, float] | None = None,
                        size: float | None = None) -> cameras.TopDown:
        """A top-down camera over the room, or over a ``size`` x ``size`` square around ``centre``."""
        if centre is None or size is None:
            return cameras.TopDown(*self.room.size, width)
        return cameras.TopDown(size, size, width, margin=0.0, centre=centre)

    def render_top_down(self, cam: cameras.TopDown) -> np.ndarray:
        """Top-down RGB image (H, W, 3) uint8."""
        self.sync()
        rgb, _ = cameras.render(self.client, cam.width, cam.height, cam.view, cam.proj)
        return rgb
