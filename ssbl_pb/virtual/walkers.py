"""Scripted people for the deploy benchmark's faults (``SimRobot.walkers``, the virtual Pepper's ``--walker``):
``MemberStep``, a member who walks toward the robot's path while out of its camera's view, and ``Stranger``, a
person who was never seen (spawned out of view, in a colour the colour detector does not look for, as a real
detector misses someone) stepping into the robot's path. Each is stepped after the world's own step and overrides
the social force model for the person it moves. Neither walks into the robot: a walker stops where its body would
come within ``WALKER_KEEP`` of the footprint, so an intimate-zone entry is the robot's doing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.range_memory import WALK_SPEED
from ..core.range_sensors import in_laser_fields
from ..deploy.robot import relative
from ..env.view.bullet import pybullet as p
from ..env.view.world import World, box_circle_distance
from ..urdf import urdf_path

WALKER_KEEP = 0.6  # m between a walker's body and the footprint where it stops (ours: people do not walk into a
#   robot; above the intimate zone's 0.45 m, so a walker never makes an entry itself)
STRANGER_COLOUR = (0.55, 0.55, 0.55, 1)  # grey: none of ``urdf.HUMAN_COLOURS``, so the colour detector misses them
MOVING = 0.1  # m/s: the robot counts as driving (a fault waits for this)
WALKERS = ("member", "stranger")


def stranger_body(client: int) -> int:
    """A person's body in ``STRANGER_COLOUR`` in a PyBullet scene, parked below the floor."""
    body = p.loadURDF(str(urdf_path("human")), [0, 0, -10], useFixedBase=True, physicsClientId=client)
    p.changeVisualShape(body, 0, rgbaColor=STRANGER_COLOUR, physicsClientId=client)
    return body


def place(client: int, body: int, x: float, y: float, yaw: float) -> None:
    p.resetBasePositionAndOrientation(body, [x, y, 0.0], [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)],
                                      physicsClientId=client)


class StrangerBodies:
    """Strangers' bodies in another scene (the virtual Pepper's camera process), made as they appear."""

    def __init__(self) -> None:
        self.bodies: list[int] = []

    def show(self, client: int, poses: np.ndarray) -> None:
        """Put one body at each pose (k, 3: x, y, yaw)."""
        while len(self.bodies) < len(poses):
            self.bodies.append(stranger_body(client))
        for body, (x, y, yaw) in zip(self.bodies, poses, strict=False):
            place(client, body, float(x), float(y), float(yaw))


def out_of_view(world: World, xy: np.ndarray) -> bool:
    """Whether a person's whole body (``human_radius`` either side) lies outside the camera's horizontal field."""
    x, y, yaw = world.robot_pose
    d = math.hypot(xy[0] - x, xy[1] - y)
    bearing = abs(math.remainder(math.atan2(xy[1] - y, xy[0] - x) - yaw, 2 * math.pi))
    half = math.radians(world.robot_params.camera_hfov_deg) / 2
    return bearing > half + math.atan2(world.social.human_radius, max(d, 1e-6))


def body_clearance(world: World, xy: np.ndarray) -> float:
    """Gap (m) between a body circle at ``xy`` and the robot's footprint (as ``World.human_clearance``)."""
    half = (world.robot_params.length / 2, world.robot_params.width / 2)
    return float(box_circle_distance(world.robot_pose, half, xy)[0]) - world.social.human_radius


def motion(world: World) -> tuple[np.ndarray, float]:
    """The robot's direction of travel (unit, room frame) and its planar speed (m/s)."""
    vx, vy, _ = world.base.body_velocity
    yaw = world.robot_pose[2]
    v = np.array([math.cos(yaw) * vx - math.sin(yaw) * vy, math.sin(yaw) * vx + math.cos(yaw) * vy])
    speed = float(np.hypot(*v))
    return (v / speed if speed > 1e-9 else np.zeros(2)), speed


class Walker:
    """A person walking to a target at ``speed`` (m/s), stopping at ``WALKER_KEEP`` from the robot."""

    kind = ""

    def __init__(self, speed: float = WALK_SPEED, start_after: float = 2.0) -> None:
        self.speed, self.start_after = speed, start_after
        self.phase = "waiting"
        self.pos: np.ndarray | None = None
        self.vel = np.zeros(2)
        self.target: np.ndarray | None = None
        self.triggered_at: float | None = None

    def walk(self, world: World, dt: float) -> bool:
        """One step toward ``target``; True once there (or blocked by the robot)."""
        d = self.target - self.pos
        dist = float(np.hypot(*d))
        step = min(self.speed * dt, dist)
        nxt = self.pos + (d / dist * step if dist > 1e-9 else 0.0)
        gap = body_clearance(world, nxt)
        if gap < WALKER_KEEP and gap < body_clearance(world, self.pos):  # closing in on the robot: stop
            self.vel = np.zeros(2)
            return True
        self.vel, self.pos = (nxt - self.pos) / dt, nxt
        return step >= dist - 1e-9

    def step(self, world: World, dt: float) -> None:
        raise NotImplementedError

    def clearance(self, world: World) -> float:
        """The walker's own body's gap to the footprint (inf where it is a group member: counted there)."""
        return math.inf

    def truth(self) -> dict[str, Any]:
        return {"kind": self.kind, "phase": self.phase, "triggered_at": self.triggered_at,
                "pos": None if self.pos is None else self.pos.tolist()}


class MemberStep(Walker):
    """Once the robot drives (after ``start_after`` s) toward a member out of the camera's view (the member ahead
    along its motion, within ``lateral`` m of that line, at least ``WALKER_KEEP`` from the footprint), that member
    walks ``distance`` toward the robot's path (the nearest point of the line along its motion), stands there
    ``hold_s``, then the social force model has them again."""

    kind = "member"

    def __init__(self, distance: float = 0.5, lateral: float = 1.6, hold_s: float = 3.0, **kw: Any) -> None:
        super().__init__(**kw)
        self.distance, self.lateral, self.hold_s = distance, lateral, hold_s
        self.k = -1
        self.until = math.inf

    def _trigger(self, world: World) -> None:
        u, speed = motion(world)
        if world.t < self.start_after or speed < MOVING:
            return
        g, robot = world.group, world.robot_pose[:2]
        clear = world.human_clearance()
        for k in np.argsort(clear):
            here = g.pos[k].copy()
            ahead = float((here - robot) @ u)
            path = robot + u * ahead
            offset = float(np.hypot(*(path - here)))
            if clear[k] >= WALKER_KEEP and ahead > 0 and offset <= self.lateral and out_of_view(world, here):
                d = (path - here) / max(offset, 1e-9)
                self.k, self.pos, self.phase = int(k), here, "walking"
                self.target, self.triggered_at = here + d * min(self.distance, offset), world.t
                return

    def step(self, world: World, dt: float) -> None:
        g = world.group
        if self.phase == "waiting":
            self._trigger(world)
            return
        if self.phase == "walking" and self.walk(world, dt):
            self.phase, self.until, self.vel = "standing", world.t + self.hold_s, np.zeros(2)
        if self.phase == "standing" and world.t >= self.until:
            self.phase = "done"
        if self.phase in ("walking", "standing"):
            g.pos[self.k], g.vel[self.k] = self.pos, self.vel


class Stranger(Walker):
    """A person the camera never sees: once the robot drives (after ``start_after`` s) with every member more than
    1 m away, they appear ``side`` m to one side of the point ``ahead`` m along its motion (out of the camera's view
    but in a laser's field, inside the room, on the side away from the group where one of ``places`` fits), walk
    to that point,
    stand in the path ``wait_s``, then walk back the way they came. (Someone who stays in the lasers' blind sectors,
    30-70 deg to either side, is seen by nothing on a Pepper: docs/deploy.md, "Limits".)"""

    kind = "stranger"

    def __init__(self, places: tuple[tuple[float, float], ...] = ((2.5, 2.0), (2.2, 1.8), (2.0, 1.6)),
                 wait_s: float = 4.0, **kw: Any) -> None:
        """``places``: (ahead, side) in m, tried in turn (the first that is out of view and in a laser's field)."""
        super().__init__(**kw)
        self.places, self.wait_s = places, wait_s
        self.body: int | None = None
        self.start = np.zeros(2)
        self.across = np.zeros(2)
        self.until = math.inf

    def attach(self, world: World) -> None:
        """The stranger's body in the world's PyBullet scene (parked below the floor until they appear)."""
        self.body = stranger_body(world.client)

    def _appear(self, world: World) -> None:
        u, speed = motion(world)
        if world.t < self.start_after or speed < MOVING or world.human_clearance().min() < 1.0:
            return
        sx, sy = world.room.size
        robot, centre, normal = world.robot_pose[:2], world.group.centre, np.array([-u[1], u[0]])
        for ahead, side in self.places:
            stop = robot + u * ahead
            for s in sorted((1.0, -1.0), key=lambda s: -float((s * normal) @ (stop - centre))):  # away from the group
                start = stop + s * side * normal
                inside = all(abs(v[i]) < lim / 2 - 0.5 for v in (start, stop) for i, lim in enumerate((sx, sy)))
                seen = in_laser_fields(relative(world.robot_pose, np.array([*start, 0.0]))[None, :2])[0]
                if inside and seen and out_of_view(world, start):
                    self.pos, self.start, self.target, self.across = start, start.copy(), stop, -s * normal
                    self.phase, self.triggered_at = "walking", world.t
                    return

    def step(self, world: World, dt: float) -> None:
        if self.phase == "waiting":
            self._appear(world)
        elif self.phase == "walking" and self.walk(world, dt):
            self.phase, self.until, self.vel = "standing", world.t + self.wait_s, np.zeros(2)
        elif self.phase == "standing" and world.t >= self.until:
            self.phase, self.target = "leaving", self.start
        elif self.phase == "leaving" and self.walk(world, dt):
            self.phase, self.vel = "done", np.zeros(2)
        if self.body is not None and self.pos is not None:
            place(world.client, self.body, *self.pos, math.atan2(self.across[1], self.across[0]))

    def clearance(self, world: World) -> float:
        return math.inf if self.pos is None else body_clearance(world, self.pos)


def make_walker(kind: str) -> Walker:
    """A scripted walker by name (``WALKERS``)."""
    if kind == "member":
        return MemberStep()
    if kind == "stranger":
        return Stranger()
    raise ValueError(f"walker {kind!r}: expected one of {WALKERS}")
