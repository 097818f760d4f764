"""The narrow robot interface the deploy loop runs on, its command clamp, and the simulated robot.

``Robot`` is all the loop knows of a robot: the newest camera frame with its time stamp, the odometry pose and
velocity, the base's range returns (lasers and sonars, ``ranges``), a velocity command that returns what was
actually sent after clamping, stop and close.
``naoqi.NaoqiRobot`` speaks to a Pepper (the only client module importing ``qi``); ``virtual.robot.SimRobot`` is the
PyBullet world and a conversation group moving by the social force model (``env``), for tests without qi and
behind the virtual Pepper (``virtual.pepper``).

Frames: the odometry frame is the robot's own (NAOqi's ``getRobotPosition(True)``: fixed in the room, origin
wherever odometry started); velocities are body-frame (forward, left, turn) in m/s and rad/s.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import numpy as np

from ..core.base import limit_command
from ..params import RobotParams


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


@dataclasses.dataclass(frozen=True)
class RangeScan:
    """The base's range returns (``deploy.ranges``): robot-frame points (k, 2) of everything the lasers and sonars
    hit, metres, when they were measured (s, on the clock of ``Odometry.stamp``), and how many of the points (the
    last) are sonar echoes (on the sonar's axis: where in its cone the echo came from is unknown)."""

    points: np.ndarray
    stamp: float
    sonars: int = 0


class Robot(Protocol):
    """What the deploy loop needs of a robot; every call returns or raises within a bounded time."""

    def frame(self) -> Frame | None:
        """The newest camera frame (None before the first one)."""
        ...

    def odometry(self) -> Odometry:
        ...

    def ranges(self) -> RangeScan | None:
        """The newest range returns; None for a robot without range sensors."""
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
