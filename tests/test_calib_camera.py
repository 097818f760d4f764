"""PinholeCamera: YAML round trip, projection inverses, ground plane, and the sim camera matching OpenCV."""

import math

import numpy as np
import pybullet as p
import pytest

from ssbl_pb.env.view import cameras
from ssbl_pb.params import CalibrationError, RobotParams
from ssbl_pb.perception.camera import PinholeCamera, sim_projection_from_yaml

DIST = np.array([-0.28, 0.09, 0.0012, -0.0008, 0.0])


def make_cam(**kw) -> PinholeCamera:
    K = np.array([[535.0, 0.0, 322.5], [0.0, 533.0, 241.2], [0.0, 0.0, 1.0]])
    args = dict(width=640, height=480, K=K, dist=DIST, camera_height=1.15, pitch_deg=12.0, roll_deg=1.5,
                forward=0.05, extrinsics_calibrated=True)
    args.update(kw)
    return PinholeCamera(**args)


def test_yaml_round_trip(tmp_path):
    cam = make_cam()
    path = cam.to_yaml(tmp_path / "cam.yaml")
    back = PinholeCamera.from_yaml(path)
    assert np.allclose(back.K, cam.K) and np.allclose(back.dist, cam.dist)
    got = (back.width, back.height, back.camera_height, back.pitch_deg, back.roll_deg)
    assert got == (640, 480, 1.15, 12.0, 1.5)
    assert back.extrinsics_calibrated
    assert not list(tmp_path.glob(".*"))  # no temporary left behind


def test_yaml_errors_name_file_and_field(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [1, 2]}\n"
                   "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
    with pytest.raises(CalibrationError, match=r"bad\.yaml.*camera_matrix"):
        PinholeCamera.from_yaml(bad)
    bad.write_text("image_width: 640\n")
    with pytest.raises(CalibrationError, match="missing key"):
        PinholeCamera.from_yaml(bad)


def test_project_unproject_inverse():
    cam = make_cam()
    rng = np.random.default_rng(0)
    pts = np.stack([rng.uniform(-1, 1, 200), rng.uniform(-0.7, 0.7, 200), rng.uniform(1.5, 6, 200)], axis=1)
    uv = cam.project(pts)
    back = cam.unproject(uv, depth=pts[:, 2])
    assert np.abs(back - pts).max() < 1e-6
    assert np.isnan(cam.project(np.array([[0.0, 0.0, -1.0]]))).all()


def test_ground_pixel_inverse_and_geometry():
    cam = make_cam()
    rng = np.random.default_rng(1)
    xy = np.stack([rng.uniform(1.5, 8, 300), rng.uniform(-2, 2, 300)], axis=1)
    uv = cam.ground_to_pixel(xy)
    inside = (uv[:, 0] > 0) & (uv[:, 0] < 640) & (uv[:, 1] > 0) & (uv[:, 1] < 480)
    assert inside.sum() > 100
    assert np.abs(cam.pixel_to_ground(uv[inside]) - xy[inside]).max() < 1e-6
    # an undistorted camera with no roll: the principal point sees the floor at h / tan(pitch) ahead
    flat = make_cam(dist=np.zeros(5), roll_deg=0.0)
    g = flat.pixel_to_ground(np.array([[flat.cx, flat.cy]]))[0]
    assert g == pytest.approx([0.05 + 1.15 / math.tan(math.radians(12.0)), 0.0], abs=1e-9)
    # rays above the horizon do not hit the floor
    assert np.isnan(flat.pixel_to_ground(np.array([[320.0, 0.0]]))).all()


def test_scaled_keeps_pixel_centres():
    cam = make_cam()
    small = cam.scaled(160, 120)
    pts = np.array([[0.3, -0.2, 3.0], [-0.5, 0.4, 2.0]])
    a = (cam.project(pts) + 0.5) / 4.0 - 0.5
    assert np.allclose(small.project(pts), a, atol=1e-9)


def _render_marker(width, height, cam, robot, pose, world_pt):
    client = p.connect(p.DIRECT)
    try:
        half = 0.025 * world_pt[0]
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.002, half, half], rgbaColor=[1, 0, 0, 1],
                                  physicsClientId=client)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        w = [pose[0] + c * world_pt[0] - s * world_pt[1], pose[1] + s * world_pt[0] + c * world_pt[1],
             world_pt[2]]
        body = p.createMultiBody(0, -1, vis, w, [0, 0, math.sin(pose[2] / 2), math.cos(pose[2] / 2)],
                                 physicsClientId=client)
        proj = cameras.projection_from_intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, width, height)
        _, seg = cameras.render(client, width, height, cameras.first_person_view(pose, robot), proj, True)
        ys, xs = np.nonzero(seg == body)
        return np.array([xs.mean(), ys.mean()]), len(xs)
    finally:
        p.disconnect(client)


@pytest.mark.parametrize("size", [(320, 240), (96, 96)])
def test_sim_camera_matches_opencv(size):
    """A world point lands on the same pixel in the TinyRenderer camera and in the OpenCV model."""
    w, h = size
    cam = make_cam(dist=np.zeros(5), roll_deg=0.0).scaled(w, h)
    robot = RobotParams(camera_height=cam.camera_height, camera_pitch_deg=cam.pitch_deg,
                        camera_forward=cam.forward)
    pose = np.array([0.4, -0.3, 0.7])
    errs = []
    for pt in ([3.0, 0.4, 0.9], [2.5, -0.5, 0.3], [4.0, 0.2, 1.5]):
        pix, n = _render_marker(w, h, cam, robot, pose, np.array(pt))
        assert n >= 4
        errs.append(pix - cam.robot_to_pixel(np.array(pt))[0])
    errs = np.array(errs)  # centroids of rasterised squares: quantisation up to ~0.5 px each
    assert np.abs(errs.mean(axis=0)).max() < 0.25 and np.abs(errs).max() < 0.6, errs


def test_gl_matrices_equal_opencv_projection(tmp_path):
    """View x projection and the OpenCV pinhole agree to 1e-4 px (float32), with TinyRenderer's offsets."""
    cam = make_cam(dist=np.zeros(5), roll_deg=0.0)
    path = cam.to_yaml(tmp_path / "cam.yaml")
    w, h = 128, 96
    small = cam.scaled(w, h)
    P = np.array(sim_projection_from_yaml(path, w, h)).reshape(4, 4, order="F")
    robot = RobotParams(**{k: v for k, v in cam.robot_overrides().items() if k.startswith("camera_")
                           and "fov" not in k})
    V = np.array(cameras.first_person_view(np.zeros(3), robot)).reshape(4, 4, order="F")
    pts = np.array([[3.0, 0.4, 0.9], [2.0, -0.6, 0.2], [5.0, 1.0, 1.6]])
    clip = (P @ V @ np.c_[pts, np.ones(3)].T).T
    ndc = clip[:, :3] / clip[:, 3:]
    # TinyRenderer: column = (x_ndc + 1) W / 2, row = (1 - y_ndc) H / 2 - 1
    tiny = np.stack([(ndc[:, 0] + 1) * w / 2, (1 - ndc[:, 1]) * h / 2 - 1], axis=1)
    assert np.abs(tiny - small.robot_to_pixel(pts)).max() < 1e-4
