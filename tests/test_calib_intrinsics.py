"""Camera intrinsics on the real OpenCV chessboard photographs, bad images, and the floor-board pose."""

import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from ssbl_pb.calib.extrinsics import pose_from_image
from ssbl_pb.calib.intrinsics import _fit, board_points, calibrate, leave_k_out, parse_board
from ssbl_pb.params import CalibrationError
from ssbl_pb.perception.camera import PinholeCamera

BOARD, SQUARE = (9, 6), 0.025


_CACHE: dict = {}


@pytest.fixture
def left_result(shared_data):
    """The left set calibrated once per test session (fix aspect, as OpenCV's sample)."""
    if "left" not in _CACHE:
        paths = sorted((shared_data / "calib").glob("left*.jpg"))
        _CACHE["left"] = calibrate(paths, BOARD, SQUARE, fix_aspect=True)
    return _CACHE["left"]


def test_left_set_rms_and_intrinsics(left_result):
    r = left_result
    assert r.rms <= 0.5
    assert r.camera.fx == r.camera.fy  # aspect ratio fixed, as OpenCV's sample does for the left set
    assert r.camera.fx == pytest.approx(533.3, rel=0.01)
    assert (r.camera.cx, r.camera.cy) == pytest.approx((342.1, 234.4), abs=3.0)
    assert len(r.detections.paths) == 13 and not r.detections.rejected
    assert r.per_image.max() < 0.3


def test_outlier_image_is_rejected(left_result):
    corners = [c.copy() for c in left_result.detected_corners]
    corners[4] += np.random.default_rng(0).normal(0, 2.0, corners[4].shape).astype(np.float32)
    obj = board_points(BOARD, SQUARE)
    keep, fit, err, dropped = _fit(obj, corners, (640, 480), left_result.flags, 3.0, 5)
    assert [i for i, _ in dropped] == [4] and "outlier" in dropped[0][1] and len(keep) == 12
    assert fit[0] < 0.25


def test_left_set_leave_3_out_stable(left_result):
    """fx, cx and cy within 1 % when any 3 of the 13 images are left out (all 286 subsets)."""
    rel = leave_k_out(left_result, BOARD, SQUARE, k=3)
    assert rel.shape == (286, 4)
    assert np.abs(rel[:, [0, 2, 3]]).max() < 0.01


def test_bad_images_are_listed_not_fatal(left_result, tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 200, np.uint8))
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"not an image")
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((240, 320), np.uint8))
    paths = list(left_result.detections.paths[:6]) + [blank, junk, small]
    r = calibrate(paths, BOARD, SQUARE, fix_aspect=True)
    why = {p.name: w for p, w in r.detections.rejected}
    assert "no 9x6 chessboard" in why["blank.png"] and "not a readable image" in why["junk.jpg"]
    assert "differs" in why["small.png"] and len(r.detections.paths) == 6


def test_wrong_board_or_too_few_images_fail_clearly(left_result):
    paths = left_result.detections.paths[:4]
    with pytest.raises(CalibrationError, match=r"only 0 of 4 .*check --board"):
        calibrate(paths, (9, 7), SQUARE)
    with pytest.raises(CalibrationError, match=r"9x6 board is visible .* larger than --board 8x6"):
        calibrate(left_result.detections.paths, (8, 6), SQUARE)
    with pytest.raises(CalibrationError, match="only 4 of 4 images usable, need 5"):
        calibrate(paths, BOARD, SQUARE)
    with pytest.raises(CalibrationError, match="COLSxROWS"):
        parse_board("nine by six")


def _floor_board_image(cam: PinholeCamera, centre: tuple[float, float], square: float) -> np.ndarray:
    """Render a 10x7-square board lying on the floor, seen by ``cam`` (supersampled 3x, then blurred)."""
    s = 3
    big = cam.scaled(cam.width * s, cam.height * s)
    v, u = np.mgrid[0:big.height, 0:big.width]
    g = big.pixel_to_ground(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))
    bx = (g[:, 0] - centre[0]) / square + 5.0  # 10 squares along x, 7 along y, board centred at ``centre``
    by = (g[:, 1] - centre[1]) / square + 3.5
    inside = (bx >= 0) & (bx < 10) & (by >= 0) & (by < 7)
    black = inside & ((np.floor(bx) + np.floor(by)) % 2 == 0)
    img = np.full(len(g), 235.0)
    img[black] = 20.0
    img[~inside & np.isfinite(g[:, 0])] = 150.0  # grey floor around a white margin-less board
    img = img.reshape(big.height, big.width)
    img = cv2.resize(img, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    return np.clip(img, 0, 255).astype(np.uint8)


def test_camera_pose_from_floor_board():
    K = np.array([[540.0, 0, 322.0], [0, 540.0, 238.0], [0, 0, 1]])
    truth = PinholeCamera(640, 480, K, np.array([-0.1, 0.02, 0, 0, 0]), camera_height=1.15, pitch_deg=25.0,
                          roll_deg=2.0, forward=0.05)
    img = _floor_board_image(truth, (2.0, 0.1), 0.1)
    guess = PinholeCamera(640, 480, K, truth.dist)  # intrinsics known, pose unknown (defaults)
    r = pose_from_image(guess, img, BOARD, 0.1, where="floor.png")
    assert r.rms_px < 0.3
    assert r.height == pytest.approx(1.15, abs=0.01)
    assert r.pitch_deg == pytest.approx(25.0, abs=0.3) and r.roll_deg == pytest.approx(2.0, abs=0.3)
    assert r.board_centre_seen == pytest.approx([2.0, 0.1], abs=0.03)
    assert r.camera.extrinsics_calibrated
    with pytest.raises(CalibrationError, match=r"floor\.png: no 9x6"):
        pose_from_image(guess, np.full((480, 640), 128, np.uint8), BOARD, 0.1, where="floor.png")
    assert math.isfinite(r.height)


TOOLS = Path(__file__).resolve().parents[1] / "tools"


def _tool(name, *args):
    return subprocess.run([sys.executable, str(TOOLS / name), *map(str, args)], capture_output=True, text=True,
                          timeout=120)


def test_calibrate_camera_cli(shared_data, tmp_path):
    imgs = sorted((shared_data / "calib").glob("left*.jpg"))[:7]
    out = tmp_path / "cam.yaml"
    proc = _tool("calibrate_camera.py", *imgs, "--board", "9x6", "--square", "0.025", "--fix-aspect", "--out", out)
    assert proc.returncode == 0, proc.stderr
    cam = PinholeCamera.from_yaml(out)
    assert cam.fx == pytest.approx(533, rel=0.02) and cam.fx == cam.fy
    assert out.with_suffix(".png").is_file() and "RMS reprojection error" in out.with_suffix(".md").read_text()
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 200, np.uint8))
    bad_out = tmp_path / "bad.yaml"
    proc = _tool("calibrate_camera.py", blank, tmp_path / "missing.jpg", "--out", bad_out)
    assert proc.returncode == 2 and "blank.png: no 9x6 chessboard found" in proc.stderr
    assert "missing.jpg: file not found" in proc.stderr and not bad_out.exists()
    proc = _tool("calibrate_camera.py", *imgs, "--board", "9by6", "--out", bad_out)
    assert proc.returncode == 2 and "COLSxROWS" in proc.stderr


def test_camera_pose_cli(tmp_path):
    K = np.array([[540.0, 0, 322.0], [0, 540.0, 238.0], [0, 0, 1]])
    truth = PinholeCamera(640, 480, K, np.zeros(5), camera_height=1.2, pitch_deg=20.0, roll_deg=-1.0)
    floor = tmp_path / "floor.png"
    cv2.imwrite(str(floor), _floor_board_image(truth, (2.2, -0.2), 0.1))
    cam_yaml = PinholeCamera(640, 480, K).to_yaml(tmp_path / "cam.yaml")
    out = tmp_path / "posed.yaml"
    proc = _tool("camera_pose.py", floor, "--camera", cam_yaml, "--square", "0.1", "--board-centre", "2.2", "-0.2",
                 "--out", out)
    assert proc.returncode == 0, proc.stderr
    cam = PinholeCamera.from_yaml(out)
    assert cam.camera_height == pytest.approx(1.2, abs=0.01) and cam.pitch_deg == pytest.approx(20.0, abs=0.3)
    assert cam.roll_deg == pytest.approx(-1.0, abs=0.3) and cam.extrinsics_calibrated
    proc = _tool("camera_pose.py", cam_yaml, "--camera", cam_yaml, "--square", "0.1", "--out", out)
    assert proc.returncode == 2 and "cam.yaml: not a readable image" in proc.stderr
