"""Camera intrinsics from chessboard photographs (OpenCV): detection, sub-pixel corners, calibrateCamera.

Images where the board is not found, that cannot be read, or whose size differs from the first readable image
are rejected with a reason and listed; calibration fails only when fewer than ``min_images`` remain.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from ..cli import progress as bar
from ..params import CalibrationError
from ..perception.camera import PinholeCamera

SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
FIND_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE


def parse_board(text: str) -> tuple[int, int]:
    """"9x6" -> (9, 6): inner corners per row (columns) and per column (rows)."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise CalibrationError(f"board {text!r}: expected inner corners as COLSxROWS, e.g. 9x6") from exc
    if cols < 2 or rows < 2:
        raise CalibrationError(f"board {text!r}: need at least 2x2 inner corners")
    return cols, rows


def board_points(board: tuple[int, int], square: float) -> np.ndarray:
    """Board corners (N, 3) in metres on the board plane z = 0, in OpenCV's detection order."""
    cols, rows = board
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    return obj


def read_grey(path: str | Path) -> np.ndarray:
    """Read an image as 8-bit grey; ``CalibrationError`` naming the file when it cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: file not found")
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise CalibrationError(f"{path}: not a readable image")
    return img


def find_corners(grey: np.ndarray, board: tuple[int, int], window: int = 11) -> np.ndarray | None:
    """Sub-pixel chessboard corners (N, 2) float32, or None when the full board is not found.

    The refinement half-window is ``window`` px, shrunk to 40 % of the smallest corner spacing so that it
    never reaches the neighbouring corners of a small (distant) board.
    """
    ok, corners = cv2.findChessboardCorners(grey, board, flags=FIND_FLAGS)
    if not ok:
        return None
    grid = corners.reshape(board[1], board[0], 2)
    spacing = min(np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
                  np.linalg.norm(np.diff(grid, axis=1), axis=2).min())
    window = int(max(2, min(window, 0.4 * spacing)))
    corners = cv2.cornerSubPix(grey, corners, (window, window), (-1, -1), SUBPIX_CRITERIA)
    return corners.reshape(-1, 2)


def larger_board(grey: np.ndarray, board: tuple[int, int]) -> tuple[int, int] | None:
    """A board one corner wider or taller than ``board`` when one is visible (a too-small --board matches a
    sub-grid of the real board), else None."""
    for size in ((board[0] + 1, board[1]), (board[0], board[1] + 1)):
        ok, _ = cv2.findChessboardCorners(grey, size, flags=FIND_FLAGS | cv2.CALIB_CB_FAST_CHECK)
        if ok:
            return size
    return None


@dataclasses.dataclass
class Detections:
    """Corners found per image, the rejected images with their reasons, and the common image size."""

    paths: list[Path]
    corners: list[np.ndarray]
    rejected: list[tuple[Path, str]]
    size: tuple[int, int] | None  # (width, height)
    larger: list[tuple[Path, tuple[int, int]]] = dataclasses.field(default_factory=list)  # checked on 5


def detect(paths: Iterable[str | Path], board: tuple[int, int], progress: bool = False) -> Detections:
    """Detect the board in every image; never raises for one bad image (it is listed in ``rejected``)."""
    paths = [Path(p) for p in paths]
    it: Iterable[Path] = paths
    if progress:
        it = bar(paths, "detecting corners", "img")
    out = Detections([], [], [], None)
    for path in it:
        try:
            grey = read_grey(path)
        except CalibrationError as exc:
            out.rejected.append((path, str(exc).split(": ", 1)[-1]))
            continue
        size = (grey.shape[1], grey.shape[0])
        if out.size is not None and size != out.size:
            out.rejected.append((path, f"size {size[0]}x{size[1]} differs from {out.size[0]}x{out.size[1]}"))
            continue
        corners = find_corners(grey, board)
        if corners is None:
            out.rejected.append((path, f"no {board[0]}x{board[1]} chessboard found"))
            continue
        if len(out.paths) < 5:  # a too-small --board matches a sub-grid: look for a larger one
            bigger = larger_board(grey, board)
            if bigger is not None:
                out.larger.append((path, bigger))
        out.size = out.size or size
        out.paths.append(path)
        out.corners.append(corners)
    return out


@dataclasses.dataclass
class IntrinsicsResult:
    """A calibrated camera with its fit quality."""

    camera: PinholeCamera
    rms: float  # px, OpenCV's overall RMS reprojection error over the kept images
    per_image: np.ndarray  # px, RMS reprojection error of each kept image
    std_intrinsics: np.ndarray  # 1-sigma of fx, fy, cx, cy, k1, k2, p1, p2, k3 (OpenCV's estimate)
    detections: Detections  # kept images only; rejected ones (no board, outliers) in detections.rejected
    detected_corners: list[np.ndarray]  # all images where the board was found, before outlier rejection
    rvecs: list[np.ndarray]
    tvecs: list[np.ndarray]
    flags: int
    outlier_factor: float


def _calibrate(obj: np.ndarray, corners: Sequence[np.ndarray], size: tuple[int, int], flags: int
               ) -> tuple[float, np.ndarray, np.ndarray, list, list, np.ndarray]:
    objs = [obj] * len(corners)
    imgs = [c.reshape(-1, 1, 2).astype(np.float32) for c in corners]
    K0 = np.eye(3)  # aspect ratio 1 when it is fixed
    rms, K, dist, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(objs, imgs, size, K0, None,
                                                                        flags=flags)
    return float(rms), K, dist.ravel(), list(rvecs), list(tvecs), std.ravel()


def _per_image(obj: np.ndarray, corners: Sequence[np.ndarray], K: np.ndarray, dist: np.ndarray,
               rvecs: list, tvecs: list) -> np.ndarray:
    out = []
    for c, r, t in zip(corners, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj, r, t, K, dist)
        out.append(float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - c) ** 2, axis=1)))))
    return np.array(out)


def _fit(obj: np.ndarray, corners: list[np.ndarray], size: tuple[int, int], flags: int, outlier_factor: float,
         min_images: int) -> tuple[list[int], tuple, np.ndarray, list[tuple[int, str]]]:
    """Calibrate, drop the worst image while its error exceeds ``outlier_factor`` x the median, refit."""
    keep = list(range(len(corners)))
    dropped: list[tuple[int, str]] = []
    while True:
        fit = _calibrate(obj, [corners[i] for i in keep], size, flags)
        err = _per_image(obj, [corners[i] for i in keep], fit[1], fit[2], fit[3], fit[4])
        worst = int(np.argmax(err))
        med = float(np.median(err))
        if outlier_factor <= 0 or err[worst] <= outlier_factor * med or len(keep) <= min_images:
            return keep, fit, err, dropped
        why = f"outlier: reprojection error {err[worst]:.2f} px > {outlier_factor:g} x median {med:.2f} px"
        dropped.append((keep[worst], why))
        del keep[worst]


def calibrate(paths: Iterable[str | Path], board: tuple[int, int], square: float, fix_aspect: bool = False,
              zero_tangent: bool = False, fix_k3: bool = False, outlier_factor: float = 3.0,
              min_images: int = 5, progress: bool = False, name: str = "camera") -> IntrinsicsResult:
    """Calibrate from chessboard photographs; ``CalibrationError`` if fewer than ``min_images`` are usable.

    Images whose reprojection error exceeds ``outlier_factor`` times the median are rejected one at a time
    (worst first) and the camera refitted; 0 disables this.
    """
    if not square > 0:
        raise CalibrationError(f"square = {square!r}: expected the square size in metres (> 0)")
    paths = list(paths)
    if not paths:
        raise CalibrationError("no images given")
    det = detect(paths, board, progress)
    if len(det.paths) < min_images:
        why = "; ".join(f"{p}: {r}" for p, r in det.rejected[:6])
        hint = " (check --board: inner corners, COLSxROWS)" if not det.paths else ""
        raise CalibrationError(f"only {len(det.paths)} of {len(paths)} images usable, need {min_images}"
                               f"{hint}. Rejected: {why}")
    if det.size is None:  # unreachable: set with the first usable image
        raise CalibrationError("no usable image")
    if len(det.larger) >= 3:  # one false hit (the board's outer edge) happens; most images: a sub-grid
        p, big = det.larger[0]
        raise CalibrationError(f"{p}: a {big[0]}x{big[1]} board is visible in {len(det.larger)} of the first "
                               f"5 images, larger than --board {board[0]}x{board[1]}: check --board (inner "
                               "corners)")
    flags = ((cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0) | (cv2.CALIB_FIX_K3 if fix_k3 else 0)
             | (cv2.CALIB_ZERO_TANGENT_DIST if zero_tangent else 0))
    obj = board_points(board, square)
    all_corners = list(det.corners)
    keep, (rms, K, dist, rvecs, tvecs, std), err, dropped = _fit(obj, all_corners, det.size, flags,
                                                                  outlier_factor, min_images)
    kept = Detections([det.paths[i] for i in keep], [all_corners[i] for i in keep],
                      det.rejected + [(det.paths[i], why) for i, why in dropped], det.size)
    cam = PinholeCamera(det.size[0], det.size[1], K, dist, name=name)
    return IntrinsicsResult(cam, rms, err, std[:9], kept, all_corners, rvecs, tvecs, flags, outlier_factor)


def leave_k_out(result: IntrinsicsResult, board: tuple[int, int], square: float, k: int = 3,
                max_subsets: int | None = None, seed: int = 0, progress: bool = False) -> np.ndarray:
    """Rerun the whole fit (outlier rejection included) leaving out every ``k``-subset of detected images.

    Uses all images where the board was found (or ``max_subsets`` random subsets). Returns an array
    (n_subsets, 4) of fx, fy, cx, cy relative to the full-set values (0.01 = 1 %).
    """
    corners = result.detected_corners
    n = len(corners)
    if n - k < 3:
        raise CalibrationError(f"leave-{k}-out needs more than {k + 2} usable images, have {n}")
    subsets = list(itertools.combinations(range(n), k))
    if max_subsets is not None and len(subsets) > max_subsets:
        rng = np.random.default_rng(seed)
        subsets = [subsets[i] for i in sorted(rng.choice(len(subsets), max_subsets, replace=False))]
    it: Iterable[tuple[int, ...]] = subsets
    if progress:
        it = bar(subsets, f"leave-{k}-out", "fit")
    obj = board_points(board, square)
    ref = np.array([result.camera.fx, result.camera.fy, result.camera.cx, result.camera.cy])
    size = (result.camera.width, result.camera.height)
    out = []
    for drop in it:
        sub = [c for i, c in enumerate(corners) if i not in drop]
        _, (_, K, *_), _, _ = _fit(obj, sub, size, result.flags, result.outlier_factor, 3)
        out.append(np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2]]) / ref - 1.0)
    return np.array(out)
