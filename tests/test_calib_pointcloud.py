"""Point-cloud room fit: a synthetic scan with known height, tilt and width; the real office frame; bad input."""

import numpy as np
import pytest

from ssbl_pb.calib.pointcloud import analyse, load_points, parse_up, synthetic_room
from ssbl_pb.params import CalibrationError


def test_synthetic_scan_recovers_height_tilt_and_width():
    pts = synthetic_room(size=(6.0, 4.0), height=1.15, pitch_deg=15.0, roll_deg=2.0, noise=0.005, n=30000, seed=1)
    scan = analyse(pts, parse_up("-y"), seed=1)
    assert scan.camera_height == pytest.approx(1.15, abs=0.01)
    assert scan.pitch_deg == pytest.approx(15.0, abs=0.3) and scan.roll_deg == pytest.approx(2.0, abs=0.3)
    widths = [v for k, v in scan.room_extent.items() if k.startswith("walls")]
    assert widths and widths[0] == pytest.approx(4.0, abs=0.03)
    assert sum(p.kind == "horizontal" for p in scan.planes) >= 1  # table tops were not taken for the floor


def test_real_office_frame(shared_data):
    """PCL's office1.pcd (Kinect, optical frame, y down): the floor is ~5 % of the points."""
    pts = load_points(shared_data / "pointcloud" / "office1.pcd")
    assert len(pts) > 200000
    scan = analyse(pts, parse_up("-y"), where="office1.pcd")
    assert 0.02 < scan.floor.share < 0.1
    assert scan.camera_height == pytest.approx(1.30, abs=0.03)
    assert scan.tilt_deg < 8.0
    walls = sorted(scan.wall_distances)
    assert walls[-1] == pytest.approx(5.0, abs=0.15)  # the back wall with the door


def test_bad_input(tmp_path):
    with pytest.raises(CalibrationError, match=r"nope\.pcd: file not found"):
        load_points(tmp_path / "nope.pcd")
    junk = tmp_path / "junk.ply"
    junk.write_text("this is not a point cloud\n")
    with pytest.raises(CalibrationError, match=r"junk\.ply: 0 finite points"):
        load_points(junk)
    with pytest.raises(CalibrationError, match="up axis"):
        parse_up("w")
    rng = np.random.default_rng(0)
    wall = np.c_[rng.uniform(-2, 2, 5000), rng.uniform(-1, 1, 5000), np.full(5000, 3.0)]  # a wall, no floor
    with pytest.raises(CalibrationError, match=r"wall\.pcd: no floor plane found"):
        analyse(wall, parse_up("-y"), where="wall.pcd")
