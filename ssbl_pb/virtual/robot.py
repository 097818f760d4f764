"""The simulated robot behind the ``robot.Robot`` interface: Pepper and a conversation group in the PyBullet world
(``env``), stepped by a lockstep clock (``SimClock``: tests) or by the virtual Pepper's real-time thread
(``virtual.pepper``); its base lasers and sonars ray-cast in that world (``RangeSensors``), and scripted people
(``walkers``) for the deploy benchmark's faults."""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Iterable
from typing import Any

import numpy as np

from ..core.range_sensors import LASERS, RANGES, SONARS, Mount, RangeParams, segment_angles, sonar_angles
from ..deploy.ranges import KEYS, LASER_KEY, SONAR_KEY, scan_points
from ..deploy.robot import Frame, Odometry, RangeScan, clamp_command, relative
from ..env.gymenv.approach import ApproachGroupEnv
from ..env.view.bullet import pybullet as p
from ..env.view.world import World
from ..params import HumansLook, RobotParams, WorldParams
from .walkers import Walker

DETECTOR = {"body": "movenet", "proxy": "colour"}  # the detector deploy's --detector auto picks for each look


def exit_distance(mount: Mount, angle: float, half_length: float, half_width: float) -> float:
    """Metres from a sensor at ``mount`` along ``angle`` (its frame) to where the ray leaves the base's footprint
    box: the virtual rays start there, so they never hit the robot's own body."""
    ux, uy = math.cos(mount.yaw + angle), math.sin(mount.yaw + angle)
    t = math.inf
    for o, u, h in ((mount.x, ux, half_length), (mount.y, uy, half_width)):
        if abs(u) > 1e-12:
            t = min(t, ((h if u > 0 else -h) - o) / u)
    return max(t, 0.0) + 1e-3


class RangeSensors:
    """Pepper's base lasers and sonars (``deploy.ranges``) ray-cast in a world's PyBullet scene (``rayTestBatch``
    against the people's, walls' and obstacles' collision shapes, at the lasers' height), each sensor's last scan
    kept and cast again at its own rate (``update``); ``values`` answers ALMemory's keys from them. A laser segment
    is one ray at its centre (at 3 m the rays lie 0.21 m apart, under a person's 0.56 m); a sonar's echo is the
    nearest hit of ``sonar_rays`` rays across its cone."""

    def __init__(self, world: World, params: RangeParams = RANGES) -> None:
        self.world, self.p = world, params
        self.values: dict[str, float] = {}
        self.due: dict[str, float] = {}
        self.cast_t = 0.0  # robot time of the lasers' last frame (all three are cast together)
        rp = world.robot_params
        half = (rp.length / 2, rp.width / 2)
        self._rays = {("laser", n): (m, segment_angles(params), params.laser_max, 1.0 / params.laser_hz)
                      for n, m in LASERS.items()}
        self._rays.update({("sonar", n): (m, sonar_angles(params), params.sonar_reported_max, 1.0 / params.sonar_hz)
                           for n, m in SONARS.items()})
        self._exit = {k: np.array([exit_distance(m, a, *half) for a in angles])
                      for k, (m, angles, _, _) in self._rays.items()}

    def update(self, t: float) -> None:
        """Cast again every sensor whose period has passed at robot time ``t`` (s)."""
        due = [k for k in self._rays if self.due.get(k, -math.inf) <= t + 1e-9]
        if not due:
            return
        ranges = self.cast(due)
        for k, r in zip(due, ranges, strict=True):
            mount, angles, top, period = self._rays[k]
            self.due[k] = max(self.due.get(k, t) + period, t + 1e-9)
            if k[0] == "laser":
                self.cast_t = t
                r = np.where(np.isfinite(r), r, top)
                for j, (a, d) in enumerate(zip(angles, r, strict=True)):
                    self.values[LASER_KEY.format(k[1], j + 1, "X")] = float(d * math.cos(a))
                    self.values[LASER_KEY.format(k[1], j + 1, "Y")] = float(d * math.sin(a))
            else:
                self.values[SONAR_KEY.format(k[1])] = float(min(np.nanmin(np.where(np.isfinite(r), r, top)), top))

    def cast(self, sensors: Iterable[tuple[str, str]]) -> list[np.ndarray]:
        """Each sensor's ranges (m, inf where its ray hit nothing) from the robot's pose now."""
        w = self.world
        w.sync()
        x, y, yaw = (float(v) for v in w.robot_pose)
        c, s = math.cos(yaw), math.sin(yaw)
        froms, tos, spans, sizes = [], [], [], []
        for k in sensors:
            mount, angles, top, _ = self._rays[k]
            ox, oy = x + c * mount.x - s * mount.y, y + s * mount.x + c * mount.y
            for a, t0 in zip(angles, self._exit[k], strict=True):
                ux, uy = math.cos(yaw + mount.yaw + a), math.sin(yaw + mount.yaw + a)
                froms.append([ox + t0 * ux, oy + t0 * uy, self.p.laser_height])
                tos.append([ox + top * ux, oy + top * uy, self.p.laser_height])
                spans.append((t0, top))
            sizes.append(len(angles))
        hits = p.rayTestBatch(froms, tos, physicsClientId=w.client)
        r = np.array([t0 + h[2] * (top - t0) if h[0] >= 0 else math.inf
                      for h, (t0, top) in zip(hits, spans, strict=True)])
        return np.split(r, np.cumsum(sizes)[:-1])


class SimRobot:
    """Pepper and a conversation group in the PyBullet world (``env.gymenv.approach``'s scene, its scenarios and
    seeds), behind the ``Robot`` interface.

    Time advances only through ``advance`` and frames appear only through ``render`` (a lockstep test clock, or
    the virtual Pepper's real-time thread, drive both). Like a real Pepper, the base keeps executing the last
    command until told otherwise. Odometry starts at the robot's spawn pose (as if NAOqi had booted there), so
    the room frame (``start_pose``) is not given away.
    All methods hold one lock, so qi's threads and the stepping thread can share the robot.
    """

    def __init__(self, scenario: str = "default", seed: int = 0, limits: RobotParams | None = None,
                 image_size: tuple[int, int] = (320, 240), sim_dt: float = 0.02, appearance: str | None = None,
                 **env_kwargs: Any) -> None:
        """``limits``: the base's limits (the robot's clamp; default Pepper's NAOqi defaults); ``sim_dt``: the
        world's integration step (s); ``appearance``: how the people look in its frames (``humans.appearance``:
        "body" or "proxy"; default the ``world``'s); ``env_kwargs``: the env's ``world``/``robot``/``social``
        parameters."""
        world = env_kwargs.pop("world", None) or WorldParams()
        if isinstance(world, WorldParams):
            world = dataclasses.replace(world, dt=sim_dt)
            if appearance is not None:
                world = dataclasses.replace(world, humans=HumansLook(appearance))
        else:
            world = {**world, "dt": sim_dt, **({} if appearance is None else {"humans": {"appearance": appearance}})}
        self.env = ApproachGroupEnv(scenario, world=world, **env_kwargs)
        self.info = self.env.reset(seed=seed)[1]
        self.world = self.env.world
        self.world.set_body_seed(seed)  # ``humans.appearance: body``: the members' bodies follow the scene's seed
        self.limits = limits or self.env.robot_params
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.start_pose = self.world.robot_pose.copy()  # room frame
        self.t = 0.0  # robot clock (s)
        self._cmd = np.zeros(3)
        self._lock = threading.RLock()
        self._frame: Frame | None = None
        self.clock = time.monotonic  # stamps odometry readings; a lockstep clock replaces it
        self.closed = False
        self.sensors: RangeSensors | None = None  # cast from the first read on (``memory_values``)
        self.walkers: list[Walker] = []

    @property
    def identity(self) -> dict[str, str]:
        """What the virtual Pepper says of itself over qi (``SSBLVirtualPepper``): the detector for its people's
        look (deploy's ``--detector auto``, ``deploy.perceive.detector_for``)."""
        return {"detector": DETECTOR[self.world.params.humans.appearance],
                # what the virtual lasers hit is the people's collision cylinder: from it to a person's centre
                # (``perception.detection.laser_range``; a real Pepper's lasers hit feet and shins, 0.1 m)
                "person_laser_depth_m": f"{self.world.social.human_radius:g}"}

    # -- simulation side -------------------------------------------------------------------------------------
    def advance(self, seconds: float) -> None:
        """Run the world for ``seconds`` (whole steps of ``sim_dt``) under the current command."""
        with self._lock:
            steps = max(0, int(round(seconds / self.world.params.dt)))
            for _ in range(steps):
                self.world.step(self._cmd)
                for walker in self.walkers:
                    walker.step(self.world, self.world.params.dt)
                if self.sensors is not None:
                    self.sensors.update(self.world.t)
            self.t = self.world.t

    def add_walker(self, walker: Walker) -> None:
        """Script a person (``walkers``): stepped after each world step from now on."""
        with self._lock:
            if hasattr(walker, "attach"):
                walker.attach(self.world)
            self.walkers.append(walker)

    def render(self) -> Frame:
        """Render the camera now and make it the newest frame."""
        with self._lock:
            img, _ = self.world.render_first_person(*self.image_size)
            self._frame = Frame(img, self.t)
            return self._frame

    def scene(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What a camera needs to render the world now: time, robot pose, members' positions and headings, and the
        strangers' poses (k, 3: x, y, yaw) among the scripted walkers."""
        with self._lock:
            g = self.world.group
            extra = [[*w.pos, math.atan2(w.across[1], w.across[0])] for w in self.walkers
                     if getattr(w, "body", None) is not None and w.pos is not None]
            return self.t, self.world.robot_pose.copy(), g.pos.copy(), g.yaw.copy(), np.array(extra).reshape(-1, 3)

    def set_frame(self, frame: Frame) -> None:
        """Make a frame rendered elsewhere (``virtual.pepper``'s camera process) the newest one."""
        with self._lock:
            self._frame = frame

    def truth(self) -> dict[str, Any]:
        """Ground truth for logs and tests: room-frame poses, members (positions, velocities m/s, yaws rad), the group's
        centre, o-space radius (m) and free slot, clearances."""
        with self._lock:
            w, g = self.world, self.world.group
            clear = w.human_clearance()
            strangers = min((walker.clearance(w) for walker in self.walkers), default=math.inf)
            out = {"t": self.t, "pose": w.robot_pose.tolist(), "vel": w.base.body_velocity.tolist(),
                   "cmd": self._cmd.tolist(), "members": g.pos.tolist(), "member_vel": g.vel.tolist(),
                   "member_yaw": g.yaw.tolist(),
                   "centre": g.centre.tolist(), "radius": g.radius,
                   "slot": g.free_slot(w.robot_pose[:2]).tolist(), "clearance": float(min(clear.min(), strangers)),
                   "collision": bool(w.in_contact(clear)) or strangers <= 0.0}
            if self.walkers:
                out["walkers"] = [walker.truth() for walker in self.walkers]
            return out

    # -- Robot interface -------------------------------------------------------------------------------------
    def frame(self) -> Frame | None:
        with self._lock:
            return self._frame

    def odometry(self) -> Odometry:
        with self._lock:
            pose = relative(self.start_pose, self.world.robot_pose)
            return Odometry(pose, self.world.base.body_velocity, self.clock())

    def memory_values(self, keys: Iterable[str]) -> list[float]:
        """ALMemory's values of the base's range sensors (``deploy.ranges.KEYS``) from their last scans; the
        sensors start casting at the first call. An unknown key raises ``KeyError``."""
        with self._lock:
            if self.sensors is None:
                self.sensors = RangeSensors(self.world)
                self.sensors.update(self.world.t)
            values = self.sensors.values
            return [values[k] for k in keys]

    def ranges(self) -> RangeScan:
        """The range returns, stamped with the lasers' last frame (on the odometry clock)."""
        values = self.memory_values(KEYS)
        with self._lock:
            points, sonars = scan_points(values)
            return RangeScan(points, self.clock() - (self.world.t - self.sensors.cast_t), sonars)

    def send(self, cmd: np.ndarray) -> np.ndarray:
        with self._lock:
            self._cmd = clamp_command(cmd, self.limits)
            return self._cmd.copy()

    def stop(self) -> None:
        with self._lock:
            self._cmd = np.zeros(3)

    def close(self) -> None:
        with self._lock:
            self._cmd = np.zeros(3)
            if not self.closed:
                self.env.close()
            self.closed = True


class SimClock:
    """Lockstep time for a ``SimRobot``: ``sleep`` advances the world (rendering the camera at ``fps``), so a
    loop on this clock is deterministic; compute time costs no simulated time."""

    def __init__(self, robot: SimRobot, fps: float = 15.0) -> None:
        self.robot, self.period = robot, 1.0 / fps
        robot.clock = self.now
        robot.render()
        self._next_frame = robot.t + self.period

    def now(self) -> float:
        return self.robot.t

    def sleep(self, seconds: float) -> None:
        end = self.robot.t + max(seconds, 0.0)
        step = self.robot.world.params.dt
        while self.robot.t + 0.5 * step < end:
            self.robot.advance(step)
            if self.robot.t + 1e-9 >= self._next_frame:
                self.robot.render()
                self._next_frame = self.robot.t + self.period
