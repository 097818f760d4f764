"""Which way a person faces, as the group estimate takes it: the per-box ``Facing`` record every facing
estimator returns (the colour proxies' ``proxy_facing``, MoveNet's keypoints ``keypoints``) and the angle
conventions.

Convention: phi (rad, in (-pi, pi]) is the angle from the direction "person -> camera" to the person's facing,
counter-clockwise seen from above. phi = 0: the person looks at the camera; +-pi: their back is to it; phi > 0:
they have turned to their own left (the chest plate moves to the image's right). A person's facing yaw in the
robot frame is ``facing_yaw(xy, phi)``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np


@dataclasses.dataclass
class Facing:
    """Per torso box (rows follow the boxes). Angles in rad; see the module's docstring for the convention."""

    phi: np.ndarray  # (n,) in (-pi, pi]: circular mean of the posterior; NaN where it cannot tell
    std: np.ndarray  # (n,) its circular spread (rad); NaN where there is no posterior
    phi_abs: np.ndarray  # (n,) |phi| in [0, pi] from the posterior folded about the line of sight; NaN: no estimate
    abs_std: np.ndarray  # (n,) its spread
    front: np.ndarray  # (n,) posterior probability that |phi| < 90 deg (the front faces the camera)
    depth: np.ndarray  # (n,) m: the body axis behind the box's ground point (deploy's), along the line of sight:
    # deploy's ``perceive.torso_depth`` for the facing seen (posterior mean)
    marker: np.ndarray  # (n,) bool: the chest plate was seen
    posterior: np.ndarray  # (n, k) over ``grid``
    grid: np.ndarray  # (k,) phi hypotheses

    @classmethod
    def empty(cls, n: int, grid: np.ndarray) -> Facing:
        """``n`` rows with no estimate."""
        nan = np.full(n, np.nan)
        return cls(nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(), np.zeros(n, dtype=bool),
                   np.full((n, len(grid)), np.nan), grid)


def wrap(a: np.ndarray | float) -> np.ndarray:
    """Angles wrapped into (-pi, pi]."""
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def facing_yaw(xy: np.ndarray, phi: np.ndarray, camera_xy: Sequence[float] = (0.05, 0.0)) -> np.ndarray:
    """Robot-frame yaw (rad) each person faces: their robot-frame positions (n, 2), ``phi`` (n,) and the camera's
    ground position (``PinholeCamera.centre()[:2]``; CameraTop is 0.05 m ahead of the base centre)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    to_cam = np.arctan2(camera_xy[1] - xy[:, 1], camera_xy[0] - xy[:, 0])
    return wrap(to_cam + np.asarray(phi, dtype=float))


def phi_of(person_xy: Sequence[float], yaw: float, camera_xy: Sequence[float]) -> float:
    """The convention as a formula: phi of a person at ``person_xy`` facing ``yaw`` seen from ``camera_xy`` (any
    common frame)."""
    to_cam = math.atan2(camera_xy[1] - person_xy[1], camera_xy[0] - person_xy[0])
    return float(wrap(yaw - to_cam))
