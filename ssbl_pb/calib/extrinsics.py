"""Camera pose (height above the floor, pitch, roll) from one image of a chessboard lying on the floor.

Height, pitch and roll follow from the board's plane alone. Where the board lies is only a check: the board
centre's floor position seen through the solved pose (``board_centre_seen``, robot frame, assuming the camera
looks straight ahead) should match where it was put; a lateral offset means the camera is yawed, a forward one
that ``camera_forward`` is off. The camera's forward offset is not changed.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from ..params import CalibrationError
from ..perception.camera import PinholeCamera
from .intrinsics import board_points, find_corners


@dataclasses.dataclass
class PoseResult:
    """The camera's pose relative to the floor and the fit residuals."""

    camera: PinholeCamera  # the input camera with height, pitch and roll filled in
    height: float  # m
    pitch_deg: float
    roll_deg: float
    board_centre_seen: np.ndarray  # board centre on the floor, robot frame (m), from the solved pose
    rms_px: float  # reprojection RMS of the board corners
    corners: np.ndarray


def pose_from_board(camera: PinholeCamera, corners: np.ndarray, board: tuple[int, int], square: float
                    ) -> PoseResult:
    """Solve PnP for the floor board; height, pitch and roll follow from the floor normal alone.

    The board's detected corner order may be rotated by 180 deg, which changes nothing here: only the plane
    (its normal and distance) is used, so the result does not depend on where on the board OpenCV starts.
    """
    obj = board_points(board, square).astype(np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj, corners.reshape(-1, 1, 2).astype(np.float64), camera.K, camera.dist,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError("solvePnP failed on the floor board")
    proj, _ = cv2.projectPoints(obj, rvec, tvec, camera.K, camera.dist)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - corners.reshape(-1, 2)) ** 2, axis=1))))
    r_bc, _ = cv2.Rodrigues(rvec)  # board -> camera
    t = tvec.ravel()
    n = r_bc[:, 2]  # board normal in the optical frame
    dist = float(n @ t)  # signed distance camera -> plane along n
    up = -n if dist > 0 else n  # floor normal pointing to the camera's side
    height = abs(dist)
    # up vector in the optical frame is (-cos p sin r, -cos p cos r, -sin p) for pitch p (down +), roll r
    pitch = math.degrees(math.asin(float(np.clip(-up[2], -1.0, 1.0))))
    roll = math.degrees(math.atan2(-up[0], -up[1]))
    cam = dataclasses.replace(camera, camera_height=height, pitch_deg=pitch, roll_deg=roll,
                              extrinsics_calibrated=True)
    centre_cam = r_bc @ obj.mean(axis=0) + t
    seen = (cam.rotation() @ centre_cam + cam.centre())[:2]
    return PoseResult(cam, height, pitch, roll, seen, rms, corners)


def pose_from_image(camera: PinholeCamera, grey: np.ndarray, board: tuple[int, int], square: float,
                    where: str = "image") -> PoseResult:
    """Detect the floor board in ``grey`` and solve the pose; errors name ``where``."""
    if (grey.shape[1], grey.shape[0]) != (camera.width, camera.height):
        raise CalibrationError(f"{where}: size {grey.shape[1]}x{grey.shape[0]} differs from the calibrated "
                               f"{camera.width}x{camera.height}")
    corners = find_corners(grey, board)
    if corners is None:
        raise CalibrationError(f"{where}: no {board[0]}x{board[1]} chessboard found")
    return pose_from_board(camera, corners, board, square)
