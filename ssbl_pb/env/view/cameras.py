"""TinyRenderer cameras: Pepper's first-person CameraTop view and a top-down view for videos.

Matrices follow PyBullet's convention (16 floats, column-major OpenGL). The first-person camera keeps Pepper's
horizontal field of view (56.3 deg) at any resolution; the vertical one follows the aspect ratio (43.7 deg at
4:3, as on the real OV5640). A calibrated camera replaces the projection with one built from intrinsics
(``projection_from_intrinsics``), so that a world point lands on the same pixel as in the OpenCV model.
"""

from __future__ import annotations

import math

import numpy as np

from ...core.camera import FAR, NEAR, gl_matrix, projection_from_intrinsics  # noqa: F401 (re-exported)
from ...params import RobotParams
from .bullet import pybullet as p


def perspective(hfov_deg: float, width: int, height: int, near: float = NEAR, far: float = FAR) -> list[float]:
    """Projection with the given horizontal FOV; the vertical FOV follows ``height / width``."""
    vfov = 2.0 * math.degrees(math.atan(math.tan(math.radians(hfov_deg) / 2.0) * height / width))
    return list(p.computeProjectionMatrixFOV(vfov, width / height, near, far))


def first_person_view(pose: np.ndarray, robot: RobotParams) -> list[float]:
    """View matrix of the CameraTop optical centre for a base at ``pose`` (x, y, yaw)."""
    x, y, yaw = (float(v) for v in pose)
    c, s = math.cos(yaw), math.sin(yaw)
    eye = (x + robot.camera_forward * c, y + robot.camera_forward * s, robot.camera_height)
    pitch = math.radians(robot.camera_pitch_deg)
    fwd = (c * math.cos(pitch), s * math.cos(pitch), -math.sin(pitch))
    target = (eye[0] + fwd[0], eye[1] + fwd[1], eye[2] + fwd[2])
    up = (c * math.sin(pitch), s * math.sin(pitch), math.cos(pitch))
    return list(p.computeViewMatrix(eye, target, up))


class TopDown:
    """Camera looking straight down on a ``size_x`` x ``size_y`` area around ``centre`` (default: the room).

    TinyRenderer draws nothing through an orthographic matrix, so this is a narrow perspective camera from
    ``altitude`` metres up: the floor maps linearly to pixels (``to_pixel``), heads 1.7 m up shift outward by
    1.7/altitude (about 4 % at 40 m).
    """

    def __init__(self, size_x: float, size_y: float, width: int, margin: float = 0.3,
                 altitude: float = 40.0, centre: tuple[float, float] = (0.0, 0.0)) -> None:
        self.half_x = size_x / 2.0 + margin
        self.half_y = size_y / 2.0 + margin
        self.cx, self.cy = float(centre[0]), float(centre[1])
        self.width = int(width)
        self.height = int(round(width * self.half_y / self.half_x))
        self.view = list(p.computeViewMatrix((self.cx, self.cy, altitude), (self.cx, self.cy, 0), (0, 1, 0)))
        vfov = 2.0 * math.degrees(math.atan(self.half_y / altitude))
        self.proj = list(p.computeProjectionMatrixFOV(vfov, self.width / self.height, 1.0, altitude + 5.0))

    def to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """World (x, y) on the floor in metres -> image (u, v) pixels (float), for drawing overlays."""
        xy = np.asarray(xy, dtype=float)
        u = (xy[..., 0] - self.cx + self.half_x) / (2 * self.half_x) * self.width
        v = (self.half_y - xy[..., 1] + self.cy) / (2 * self.half_y) * self.height
        return np.stack([u, v], axis=-1)

    @property
    def pixels_per_metre(self) -> float:
        return self.width / (2 * self.half_x)


def render(client: int, width: int, height: int, view: list[float], proj: list[float],
           segmentation: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """RGB uint8 (H, W, 3) and, optionally, the segmentation mask (body ids) through TinyRenderer."""
    flags = 0 if segmentation else p.ER_NO_SEGMENTATION_MASK
    _, _, rgba, _, seg = p.getCameraImage(width, height, view, proj, shadow=0, flags=flags,
                                          renderer=p.ER_TINY_RENDERER, physicsClientId=client)
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3]
    mask = np.asarray(seg, dtype=np.int32).reshape(height, width) if segmentation else None
    return np.ascontiguousarray(rgb), mask
