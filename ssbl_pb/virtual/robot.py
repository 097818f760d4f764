"""The simulated robot behind the ``robot.Robot`` interface: Pepper and a conversation group in the PyBullet world
(``env``), stepped by a lockstep clock (``SimClock``: tests) or by the virtual Pepper's real-time thread
(``virtual.pepper``)."""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import numpy as np

from ..deploy.robot import Frame, Odometry, clamp_command, relative
from ..env.gymenv.approach import ApproachGroupEnv
from ..params import RobotParams, WorldParams


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
                 image_size: tuple[int, int] = (320, 240), sim_dt: float = 0.02, **env_kwargs: Any) -> None:
        """``limits``: the base's limits (the robot's clamp; default Pepper's NAOqi defaults); ``sim_dt``: the
        world's integration step (s); ``env_kwargs``: the env's ``world``/``robot``/``social`` parameters."""
        world = env_kwargs.pop("world", None) or WorldParams()
        world = dataclasses.replace(world, dt=sim_dt) if isinstance(world, WorldParams) else {**world, "dt": sim_dt}
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
        """Make a frame rendered elsewhere (``virtual.pepper``'s camera process) the newest one."""
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
