"""Pinhole + distortion camera read from / written to a ROS ``camera_info`` YAML, with its pose on the robot.

Frames (all metres, radians inside, degrees in files):

* optical frame: OpenCV's, x right, y down, z forward; pixels have their centres at integer coordinates.
* robot frame: x forward, y left, z up, origin on the floor under the base centre.
* the camera sits ``forward`` metres ahead of the base centre and ``height`` metres above the floor, looking
  forward and tilted down by ``pitch_deg`` (and rolled by ``roll_deg``, positive = clockwise as seen from
  behind the camera, i.e. a right-hand rotation about the robot's x axis).

YAML layout: the ROS ``camera_info`` keys (``image_width``, ``image_height``, ``camera_name``,
``camera_matrix``, ``distortion_model``, ``distortion_coefficients``, ``rectification_matrix``,
``projection_matrix``) plus the extrinsics under the ``RobotParams`` field names ``camera_height``,
``camera_pitch_deg``, ``camera_roll_deg`` and ``camera_forward`` (absent = not calibrated, defaults used).
ROS tools ignore the extra keys.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..core.camera import projection_from_intrinsics
from ..files import write_yaml
from ..params import CalibrationError, RobotParams, load_yaml

_REQUIRED = ("image_width", "image_height", "camera_matrix", "distortion_coefficients")


def _matrix(data: dict[str, Any], key: str, rows: int | None, cols: int | None, where: str) -> np.ndarray:
    block = data.get(key)
    if not isinstance(block, dict) or "data" not in block:
        raise CalibrationError(f"{where}: {key} must be a mapping with rows, cols and data")
    try:
        values = np.asarray(block["data"], dtype=float).ravel()
        r, c = int(block.get("rows", rows or 1)), int(block.get("cols", cols or values.size))
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"{where}: {key} has non-numeric entries ({exc})") from exc
    if values.size != r * c or (rows is not None and r != rows) or (cols is not None and c != cols):
        raise CalibrationError(f"{where}: {key} is {r}x{c} with {values.size} values; expected "
                               f"{rows or r}x{cols or c}")
    if not np.all(np.isfinite(values)):
        raise CalibrationError(f"{where}: {key} contains non-finite values")
    return values.reshape(r, c)


def _block(m: np.ndarray) -> dict[str, Any]:
    m = np.atleast_2d(np.asarray(m, dtype=float))
    return {"rows": int(m.shape[0]), "cols": int(m.shape[1]), "data": [float(round(v, 9)) for v in m.ravel()]}


@dataclasses.dataclass
class PinholeCamera:
    """Intrinsics ``K`` (3x3), OpenCV distortion ``dist`` (k1 k2 p1 p2 k3 ...) and the camera pose."""

    width: int
    height: int
    K: np.ndarray
    dist: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(5))
    name: str = "camera"
    camera_height: float = RobotParams.camera_height  # m above the floor
    pitch_deg: float = RobotParams.camera_pitch_deg  # downward tilt of the optical axis
    roll_deg: float = 0.0
    forward: float = RobotParams.camera_forward  # m ahead of the base centre
    extrinsics_calibrated: bool = False  # True when the pose came from calibration (written to YAML)

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=float).reshape(3, 3)
        self.dist = np.asarray(self.dist, dtype=float).ravel()
        if not (int(self.width) > 0 and int(self.height) > 0):
            raise CalibrationError(f"camera {self.name}: image size {self.width}x{self.height} must be > 0")
        if not (self.K[0, 0] > 0 and self.K[1, 1] > 0):
            raise CalibrationError(f"camera {self.name}: focal lengths fx={self.K[0, 0]}, fy={self.K[1, 1]} "
                                   "must be > 0")
        if self.camera_height <= 0:
            raise CalibrationError(f"camera {self.name}: camera_height={self.camera_height} must be > 0")

    # -- convenience -----------------------------------------------------------------------------------------
    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view of the pinhole (degrees, ignoring distortion)."""
        return (math.degrees(2 * math.atan(self.width / (2 * self.fx))),
                math.degrees(2 * math.atan(self.height / (2 * self.fy))))

    def scaled(self, width: int, height: int) -> PinholeCamera:
        """The same camera for an image resized to ``width`` x ``height`` (pixel centres kept consistent)."""
        sx, sy = width / self.width, height / self.height
        K = self.K.copy()
        K[0, 0] *= sx
        K[1, 1] *= sy
        K[0, 1] *= sx
        K[0, 2] = (self.cx + 0.5) * sx - 0.5
        K[1, 2] = (self.cy + 0.5) * sy - 0.5
        return dataclasses.replace(self, width=int(width), height=int(height), K=K)

    # -- pose ------------------------------------------------------------------------------------------------
    def rotation(self) -> np.ndarray:
        """3x3 rotation taking optical-frame vectors to the robot frame."""
        r0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        t, f = math.radians(self.pitch_deg), math.radians(self.roll_deg)
        ry = np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])
        rx = np.array([[1, 0, 0], [0, math.cos(f), -math.sin(f)], [0, math.sin(f), math.cos(f)]])
        return ry @ rx @ r0

    def centre(self) -> np.ndarray:
        """Optical centre in the robot frame (x forward, y left, z up)."""
        return np.array([self.forward, 0.0, self.camera_height])

    # -- projection ------------------------------------------------------------------------------------------
    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Optical-frame points (N, 3) -> pixels (N, 2) with distortion; NaN for points at z <= 0."""
        pts = np.asarray(points_cam, dtype=float).reshape(-1, 3)
        out = np.full((len(pts), 2), np.nan)
        ok = pts[:, 2] > 1e-9
        if ok.any():
            import cv2  # heavy: OpenCV (~0.2 s), kept out of the env's import

            uv, _ = cv2.projectPoints(pts[ok], np.zeros(3), np.zeros(3), self.K, self.dist)
            out[ok] = uv.reshape(-1, 2)
        return out

    def unproject(self, uv: np.ndarray, depth: np.ndarray | float | None = None) -> np.ndarray:
        """Pixels (N, 2) -> optical-frame rays (N, 3) with z = 1, or points at ``depth`` (z, metres)."""
        import cv2  # heavy: OpenCV (~0.2 s), kept out of the env's import

        uv = np.asarray(uv, dtype=float).reshape(-1, 1, 2)
        xy = cv2.undistortPointsIter(uv, self.K, self.dist, None, None,
                                     (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10))
        rays = np.concatenate([xy.reshape(-1, 2), np.ones((uv.shape[0], 1))], axis=1)
        if depth is None:
            return rays
        return rays * np.asarray(depth, dtype=float).reshape(-1, 1)

    def pixel_to_ground(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (N, 2), e.g. the bottom-centre of person boxes -> floor points (N, 2) in the robot frame.

        Rows whose ray does not hit the floor ahead (at or above the horizon) are NaN.
        """
        rays = self.unproject(uv) @ self.rotation().T
        c = self.centre()
        out = np.full((len(rays), 2), np.nan)
        down = rays[:, 2] < -1e-9
        t = -c[2] / rays[down, 2]
        out[down] = c[None, :2] + t[:, None] * rays[down, :2]
        return out

    def ground_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Floor points (N, 2) in the robot frame -> pixels (N, 2); NaN for points behind the camera."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        pts = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1) - self.centre()[None, :]
        return self.project(pts @ self.rotation())

    def robot_to_pixel(self, points: np.ndarray) -> np.ndarray:
        """Robot-frame 3-D points (N, 3) -> pixels (N, 2)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3) - self.centre()[None, :]
        return self.project(pts @ self.rotation())

    # -- files -----------------------------------------------------------------------------------------------
    @classmethod
    def from_yaml(cls, path: str | Path) -> PinholeCamera:
        """Read a ROS camera_info YAML (plus the optional extrinsic keys); errors name the file and field."""
        data = load_yaml(path)
        where = str(path)
        missing = [k for k in _REQUIRED if k not in data]
        if missing:
            raise CalibrationError(f"{where}: missing key(s) {missing} (ROS camera_info layout expected)")
        K = _matrix(data, "camera_matrix", 3, 3, where)
        dist = _matrix(data, "distortion_coefficients", 1, None, where).ravel()
        model = data.get("distortion_model", "plumb_bob")
        if model not in ("plumb_bob", "rational_polynomial"):
            raise CalibrationError(f"{where}: distortion_model {model!r} is not supported "
                                   "(plumb_bob or rational_polynomial)")
        kwargs: dict[str, Any] = {}
        keys = {"camera_height": "camera_height", "camera_pitch_deg": "pitch_deg",
                "camera_roll_deg": "roll_deg", "camera_forward": "forward"}
        for key, attr in keys.items():
            if key in data:
                v = data[key]
                if not isinstance(v, int | float) or not math.isfinite(v):
                    raise CalibrationError(f"{where}: {key} = {v!r}: expected a finite number")
                kwargs[attr] = float(v)
        try:
            w, h = int(data["image_width"]), int(data["image_height"])
        except (TypeError, ValueError) as exc:
            raise CalibrationError(f"{where}: image_width/image_height must be integers") from exc
        try:
            return cls(width=w, height=h, K=K, dist=dist, name=str(data.get("camera_name", "camera")),
                       extrinsics_calibrated="camera_height" in data, **kwargs)
        except CalibrationError as exc:  # the camera's own checks: name the file they read
            raise CalibrationError(f"{where}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """The YAML mapping (ROS camera_info layout + extrinsics when calibrated)."""
        P = np.zeros((3, 4))
        P[:, :3] = self.K
        data: dict[str, Any] = {
            "image_width": int(self.width), "image_height": int(self.height), "camera_name": self.name,
            "camera_matrix": _block(self.K),
            "distortion_model": "plumb_bob" if self.dist.size <= 5 else "rational_polynomial",
            "distortion_coefficients": _block(self.dist.reshape(1, -1)),
            "rectification_matrix": _block(np.eye(3)), "projection_matrix": _block(P),
        }
        if self.extrinsics_calibrated:
            data.update(camera_height=round(float(self.camera_height), 6),
                        camera_pitch_deg=round(float(self.pitch_deg), 6),
                        camera_roll_deg=round(float(self.roll_deg), 6),
                        camera_forward=round(float(self.forward), 6))
        return data

    def to_yaml(self, path: str | Path, header: str = "") -> Path:
        """Write the camera atomically."""
        return write_yaml(path, self.to_dict(), header)

    def robot_overrides(self) -> dict[str, float]:
        """``RobotParams`` fields this camera sets (field of view; pose when calibrated)."""
        hfov, vfov = self.fov_deg()
        out = {"camera_hfov_deg": hfov, "camera_vfov_deg": vfov}
        if self.extrinsics_calibrated:
            out.update(camera_height=float(self.camera_height), camera_pitch_deg=float(self.pitch_deg),
                       camera_forward=float(self.forward))
        return out


def sim_projection_from_yaml(path: str | Path, width: int, height: int) -> list[float]:
    """PyBullet projection (16 floats) matching the YAML's intrinsics for a ``width`` x ``height`` render.

    The calibrated camera is rescaled to the render size as if the real frame were resized (so fx and fy
    scale separately when the aspect ratios differ). Distortion is not rendered: compare sim frames with
    undistorted real frames (``cv2.undistort``). Pair it with ``robot_overrides()`` for the camera pose.
    """
    cam = PinholeCamera.from_yaml(path).scaled(width, height)
    return projection_from_intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, int(width), int(height))


def sim_camera(robot: RobotParams, width: int, height: int) -> PinholeCamera:
    """The pinhole equivalent of ``env.view.cameras.perspective`` + ``first_person_view`` for a render size."""
    f = width / (2.0 * math.tan(math.radians(robot.camera_hfov_deg) / 2.0))
    k = np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0 - 1.0], [0.0, 0.0, 1.0]])
    return PinholeCamera(width=width, height=height, K=k, camera_height=robot.camera_height,
                         pitch_deg=robot.camera_pitch_deg, forward=robot.camera_forward)


def pixel_to_plane(cam: PinholeCamera, uv: np.ndarray, z: float) -> np.ndarray:
    """Pixels (n, 2) -> robot-frame points (n, 2) on the horizontal plane at height ``z`` (NaN if not hit)."""
    rays = cam.unproject(np.asarray(uv, dtype=float).reshape(-1, 2)) @ cam.rotation().T
    c = cam.centre()
    out = np.full((len(rays), 2), np.nan)
    dz = rays[:, 2]
    ok = np.abs(dz) > 1e-9
    t = (z - c[2]) / np.where(ok, dz, 1.0)
    ok &= t > 0
    out[ok] = c[None, :2] + t[ok, None] * rays[ok, :2]
    return out
