"""The narrow robot interface the deploy loop runs on, its command clamp, and the simulated robot.

``Robot`` is all the loop knows of a robot: the newest camera frame with its time stamp, the odometry pose and
velocity, a velocity command that returns what was actually sent after clamping, stop and close.
``naoqi.NaoqiRobot`` speaks to a Pepper (the only client module importing ``qi``); ``SimRobot`` is the PyBullet
world and a conversation group moving by the social force model (``env``), for tests without qi and behind the
virtual Pepper (``virtual_robot``).

Frames: the odometry frame is the robot's own (NAOqi's ``getRobotPosition(True)``: fixed in the room, origin
wherever odometry started); velocities are body-frame (forward, left, turn) in m/s and rad/s.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, Protocol

import numpy as np

from ..env.approach import ApproachGroupEnv
from ..env.base import limit_command
from ..params import RobotParams, WorldParams


@dataclasses.dataclass(frozen=True)
class Frame:
    """One camera image: RGB uint8 (H, W, 3) and its capture time on the robot's clock (s)."""

    image: np.ndarray
    stamp: float


@dataclasses.dataclass(frozen=True)
class Odometry:
    """Pose (x, y, yaw) in the odometry frame, body velocity (forward, left, turn), local receive time (s)."""

    pose: np.ndarray
    velocity: np.ndarray
    stamp: float


class Robot(Protocol):
    """What the deploy loop needs of a robot; every call returns or raises within a bounded time."""

    def frame(self) -> Frame | None:
        """The newest camera frame (None before the first one)."""
        ...

    def odometry(self) -> Odometry:
        ...

    def send(self, cmd: np.ndarray) -> np.ndarray:
        """Command a body velocity; returns the command actually sent (after ``clamp_command``)."""
        ...

    def stop(self) -> None:
        """Stop the base now."""
        ...

    def close(self) -> None:
        """Stop and release the robot (camera subscriptions, connections); idempotent."""
        ...


def clamp_command(cmd: np.ndarray, limits: RobotParams) -> np.ndarray:
    """A body command (forward, left, turn) within ``limits`` (planar speed as a vector norm, turn rate);
    any non-finite entry gives a stop (zeros), never a motion."""
    c = np.asarray(cmd, dtype=float).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        return np.zeros(3)
    return limit_command(c, limits)


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """SE(2) poses: ``a`` then ``b`` expressed in ``a`` (x, y, yaw)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], math.remainder(a[2] + b[2], 2 * math.pi)])


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose ``b`` expressed in the frame of pose ``a`` (the inverse of ``compose``)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.remainder(b[2] - a[2], 2 * math.pi)])


class SimRobot:
    """Pepper and a conversation group in the PyBullet world (``env.approach``'s scene, its scenarios and
    seeds), behind the ``Robot`` interface.

    Time advances only through ``advance`` and frames appear only through ``render`` (a lockstep test clock, or
    the virtual Pepper's real-time thread, drive both). Like a real Pepper, the base keeps executing the last
    command until told otherwise. Odometry starts at the robot's spawn pose (as if NAOqi had booted there), so
    the room frame (``start_pose``) is not given away.
    All methods hold one lock, so qi's threads and the stepping thread can share the robot.
    """

    def __init__(self, scenario: str = "default", seed: int = 0, limits: RobotParams | None = None,
                 image_size: tuple[int, int] = (320, 240), sim_dt: float = 0.02, **env_kwargs: Any) -> None:
        """``limits``: the base's limits (the robot's clamp; default Pepper's NAOqi defaults); ``sim_dt``: the
        world's integration step (s); ``env_kwargs``: the env's ``world``/``robot``/``social`` parameters."""
        world = env_kwargs.pop("world", None) or WorldParams()
        world = dataclasses.replace(world, dt=sim_dt) if isinstance(world, WorldParams) else {**world, "dt": sim_dt}
        self.env = ApproachGroupEnv(scenario, world=world, **env_kwargs)
        self.info = self.env.reset(seed=seed)[1]
        self.world = self.env.world
        self.limits = limits or self.env.robot_params
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.start_pose = self.world.robot_pose.copy()  # room frame
        self.t = 0.0  # robot clock (s)
        self._cmd = np.zeros(3)
        self._lock = threading.RLock()
        self._frame: Frame | None = None
        self.clock = time.monotonic  # stamps odometry readings; a lockstep clock replaces it
        self.closed = False

    # -- simulation side -------------------------------------------------------------------------------------
    def advance(self, seconds: float) -> None:
        """Run the world for ``seconds`` (whole steps of ``sim_dt``) under the current command."""
        with self._lock:
            steps = max(0, int(round(seconds / self.world.params.dt)))
            for _ in range(steps):
                self.world.step(self._cmd)
            self.t = self.world.t

    def render(self) -> Frame:
        """Render the camera now and make it the newest frame."""
        with self._lock:
            img, _ = self.world.render_first_person(*self.image_size)
            self._frame = Frame(img, self.t)
            return self._frame

    def scene(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """What a camera needs to render the world now: time, robot pose, members' positions and headings."""
        with self._lock:
            g = self.world.group
            return self.t, self.world.robot_pose.copy(), g.pos.copy(), g.yaw.copy()

    def set_frame(self, frame: Frame) -> None:
        """Make a frame rendered elsewhere (``virtual_robot``'s camera process) the newest one."""
        with self._lock:
            self._frame = frame

    def truth(self) -> dict[str, Any]:
        """Ground truth for logs and tests: room-frame poses, members (positions, velocities m/s), the group's
        centre, o-space radius (m) and free slot, clearances."""
        with self._lock:
            w, g = self.world, self.world.group
            clear = w.human_clearance()
            return {"t": self.t, "pose": w.robot_pose.tolist(), "vel": w.base.body_velocity.tolist(),
                    "cmd": self._cmd.tolist(), "members": g.pos.tolist(), "member_vel": g.vel.tolist(),
                    "centre": g.centre.tolist(), "radius": g.radius,
                    "slot": g.free_slot(w.robot_pose[:2]).tolist(), "clearance": float(clear.min()),
                    "collision": bool(w.in_contact(clear))}

    # -- Robot interface -------------------------------------------------------------------------------------
    def frame(self) -> Frame | None:
        with self._lock:
            return self._frame

    def odometry(self) -> Odometry:
        with self._lock:
            pose = relative(self.start_pose, self.world.robot_pose)
            return Odometry(pose, self.world.base.body_velocity, self.clock())

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
