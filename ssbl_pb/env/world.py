"""The PyBullet scene: room, Pepper, a conversation group, collisions and cameras (headless DIRECT mode).

Motion is kinematic: the base (``base.HolonomicBase``) and the members (``humans.Group``) are integrated by the
compiled formulas at the control period, and their poses are pushed to PyBullet only when PyBullet is asked
something (rendering, contact queries), so PyBullet remains the scene and the renderer. The world owns its state,
or shows a batch's (``attach``: the env's state lives in ``batched.BatchedApproach``). Collisions are computed
exactly in the plane (Pepper's box footprint against the members' 0.28 m circles and the walls' inner faces);
``pybullet_contacts`` cross-checks them with PyBullet's own geometry.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..params import ConfigError, RobotParams, SocialParams, WorldParams
from ..urdf import urdf_path
from . import cameras
from .base import BaseArrays, HolonomicBase, footprint_distance, wall_clearance
from .bullet import pybullet as p
from .humans import MAX_HUMANS, Group, GroupArrays
from .layouts import GroupModel, Layout

HUMAN_COLOURS = [(0.20, 0.70, 0.30, 1), (0.20, 0.40, 0.85, 1), (0.90, 0.50, 0.10, 1), (0.60, 0.30, 0.75, 1),
                 (0.85, 0.20, 0.25, 1)]
_PARKED = (0.0, 0.0, -10.0)


@dataclasses.dataclass
class Collision:
    """One contact: ``kind`` is "human" (``index`` = member) or "wall" (``index`` 0..3 = +x, -x, +y, -y)."""

    kind: str
    index: int


def box_circle_distance(pose: np.ndarray, half: tuple[float, float], centres: np.ndarray) -> np.ndarray:
    """Distance (m) from points (k, 2) to a box footprint with half-extents ``half`` at ``pose`` (0 inside)."""
    x, y, yaw = (float(v) for v in pose[:3])
    return np.array([footprint_distance(px - x, py - y, yaw, half[0], half[1])[0]
                     for px, py in np.asarray(centres, dtype=float).reshape(-1, 2).tolist()])


def spawn_layout(rng: np.random.Generator, world: WorldParams, robot: RobotParams, social: SocialParams, n: int,
                 formation: str, start: str = "any", groups: GroupModel | None = None
                 ) -> tuple[np.ndarray, Layout, np.ndarray]:
    """A group's centre (2,) and layout (``layouts.Layout``) and the robot's pose (x, y, yaw) for one episode.

    The group (``groups``' layout for ``formation``, at a random place and rotation) keeps ``wall_margin`` from
    the walls even once the robot has joined; the robot starts ``robot_spawn_min``..``robot_spawn_max`` from its
    centre, anywhere around it or (``start="behind"``) behind a member, facing a random way.
    """
    if not isinstance(n, int | np.integer) or not 2 <= n <= MAX_HUMANS:
        raise ConfigError(f"n_humans = {n!r}: expected an integer in [2, {MAX_HUMANS}]")
    if start not in ("any", "behind"):
        raise ConfigError(f"start = {start!r}: expected 'any' or 'behind'")
    sx, sy = world.room_size
    layout = (groups or GroupModel()).layout(formation, int(n), social, rng)
    extent = max(layout.joined_radius, float(np.hypot(layout.offsets[:, 0], layout.offsets[:, 1]).max()))
    margin = extent + social.human_radius + world.wall_margin
    robot_margin = robot.length / 2 + world.wall_margin
    angles = np.arctan2(layout.offsets[:, 1], layout.offsets[:, 0])
    for _ in range(1000):
        centre = np.array([rng.uniform(-sx / 2 + margin, sx / 2 - margin),
                           rng.uniform(-sy / 2 + margin, sy / 2 - margin)])
        if start == "behind":
            k = int(rng.integers(n))
            theta = angles[k] + rng.uniform(-0.3, 0.3)
        else:
            theta = rng.uniform(0, 2 * math.pi)
        dist = rng.uniform(world.robot_spawn_min, world.robot_spawn_max)
        xy = centre + dist * np.array([math.cos(theta), math.sin(theta)])
        if abs(xy[0]) <= sx / 2 - robot_margin and abs(xy[1]) <= sy / 2 - robot_margin:
            break
    else:  # pragma: no cover - prevented by WorldParams.check_fits
        raise ConfigError(f"world.room_size = {world.room_size}: could not place a group of {n} and "
                          f"the robot after 1000 tries")
    return centre, layout, np.array([xy[0], xy[1], rng.uniform(-math.pi, math.pi)])


class World:
    """Pepper and one conversation group in a walled room; ``reset`` spawns, ``step`` advances by ``dt``."""

    def __init__(self, world: WorldParams | None = None, robot: RobotParams | None = None,
                 social: SocialParams | None = None, groups: GroupModel | None = None, keep: float = 0.0) -> None:
        """``groups``: where members stand (``layouts.GroupModel``, calibrated by default); ``keep``: the distance
        the robot's place keeps from every member's centre (``Group``, ``layouts.slot_keep``)."""
        self.params = world or WorldParams()
        self.robot_params = robot or RobotParams()
        self.social = social or SocialParams()
        self.groups = groups or GroupModel()
        self.keep = keep
        self.params.check_fits(self.social)
        self.base = HolonomicBase(self.robot_params, self.params.dt)
        self.group: Group | None = None
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
        sx, sy = self.params.room_size
        th, h = self.params.wall_thickness, self.params.wall_height
        floor_col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[sx / 2 + th, sy / 2 + th, 0.05],
                                           physicsClientId=c)
        floor_vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[sx / 2 + th, sy / 2 + th, 0.05],
                                        rgbaColor=[0.78, 0.76, 0.72, 1], physicsClientId=c)
        self.floor_id = p.createMultiBody(0, floor_col, floor_vis, [0, 0, -0.05], physicsClientId=c)
        self.wall_ids = []
        for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):  # +x, -x, +y, -y
            half = [th / 2, sy / 2 + th, h / 2] if axis == 0 else [sx / 2 + th, th / 2, h / 2]
            pos = [0.0, 0.0, h / 2]
            pos[axis] = sign * ((sx if axis == 0 else sy) / 2 + th / 2)
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=c)
            vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=[0.55, 0.55, 0.6, 1],
                                      physicsClientId=c)
            self.wall_ids.append(p.createMultiBody(0, col, vis, pos, physicsClientId=c))
        self.robot_id = p.loadURDF(str(urdf_path("pepper")), [0, 0, 0], useFixedBase=True,
                                   flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=c)
        self.human_ids = []
        for i in range(MAX_HUMANS):
            hid = p.loadURDF(str(urdf_path("human")), _PARKED, useFixedBase=True, physicsClientId=c)
            for link in (0, 1):  # torso and facing marker keep their own colours; recolour the torso only
                if link == 0:
                    p.changeVisualShape(hid, link, rgbaColor=HUMAN_COLOURS[i], physicsClientId=c)
            self.human_ids.append(hid)

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
                                            self.groups)
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
                                       *self.params.room_size))

    def in_contact(self, clearance: np.ndarray | None = None) -> bool:
        """Whether ``collisions`` would list anything (cheaper; ``clearance`` as there)."""
        clearance = self.human_clearance() if clearance is None else clearance
        return bool((len(clearance) and clearance.min() <= 0.0) or self.wall_clearance().min() <= 0.0)

    def collisions(self, clearance: np.ndarray | None = None) -> list[Collision]:
        """Robot-human and robot-wall contacts right now (``clearance``: a ``human_clearance()`` already made)."""
        clearance = self.human_clearance() if clearance is None else clearance
        out = [Collision("human", int(i)) for i in np.flatnonzero(clearance <= 0.0)]
        out += [Collision("wall", int(i)) for i in np.flatnonzero(self.wall_clearance() <= 0.0)]
        return out

    # -- PyBullet side ------------------------------------------------------------------------------------
    def sync(self) -> None:
        """Push the current poses into PyBullet (done lazily before any render or contact query)."""
        if self._synced:
            return
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
            return cameras.TopDown(*self.params.room_size, width)
        return cameras.TopDown(size, size, width, margin=0.0, centre=centre)

    def render_top_down(self, cam: cameras.TopDown) -> np.ndarray:
        """Top-down RGB image (H, W, 3) uint8."""
        self.sync()
        rgb, _ = cameras.render(self.client, cam.width, cam.height, cam.view, cam.proj)
        return rgb
