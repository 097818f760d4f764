"""SAEV keypoints as a detector (perception/autoencoding/keypoints.py) and the linear probe
(perception/autoencoding/probe.py)."""

from __future__ import annotations

import numpy as np
import pytest

from ssbl_pb.params import RobotParams
from ssbl_pb.perception.autoencoding.keypoints import calibrate, merge_points, nearest_member_distance, plane_projection
from ssbl_pb.perception.autoencoding.probe import fit_linear, fit_predict_mlp, member_probe, pixel_probe, predict_linear
from ssbl_pb.perception.camera import sim_camera


def test_calibration_finds_the_keypoint_on_the_feet_and_its_height() -> None:
    cam = sim_camera(RobotParams(), 64, 64)
    rng = np.random.default_rng(0)
    n = 200
    members = np.full((n, 5, 2), np.nan)
    members[:, 0] = np.column_stack([rng.uniform(1.5, 5, n), rng.uniform(-1, 1, n)])
    # keypoint 0 sits on member 0's feet; keypoint 1 wanders over the image
    feet = cam.ground_to_pixel(members[:, 0])
    uv = np.stack([feet, rng.uniform(0, 63, (n, 2))], axis=1)
    rho = np.column_stack([np.full(n, 0.9), rng.uniform(0, 1, n)])
    cal = calibrate(uv, rho, members, plane_projection(cam))
    assert cal.keypoints == (0,) and cal.heights == (0.0,)
    assert cal.train_median_m[0] < 1e-6


def test_nearest_member_and_merging() -> None:
    members = np.array([[[1.0, 0.0], [np.nan, np.nan]], [[np.nan, np.nan], [np.nan, np.nan]]])
    d = nearest_member_distance(np.array([[1.0, 1.0], [0.0, 0.0]]), members)
    assert d[0] == pytest.approx(1.0) and np.isnan(d[1])
    merged = merge_points(np.array([[0.0, 0.0], [0.2, 0.0], [3.0, 0.0]]), 0.5)
    assert merged.tolist() == [[0.1, 0.0], [3.0, 0.0]]


def test_linear_probe_recovers_a_linear_map() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(300, 4))
    y = x @ np.array([[1.0, 0.0], [0.5, -2.0], [0.0, 0.0], [0.0, 1.0]]) + [3.0, -1.0]
    fit = fit_linear(x, y, ridge=1e-8)
    assert np.allclose(predict_linear(fit, x), y, atol=1e-6)
    members = np.full((300, 5, 2), np.nan)
    members[:, 1] = y
    members[::3, 1] = np.nan  # member out of view in a third of the frames
    res = member_probe(x[:200], members[:200], x[200:], members[200:], ridge=1e-8)
    assert res["median_m"] < 1e-6 and res["scored"] == 67


def test_probe_splits_its_error_into_depth_and_lateral_parts() -> None:
    # member 0 stands at depth 1 or 3 m (alternating) and 0.5 m to the left; a constant predicts the means
    members = np.full((8, 2, 2), np.nan)
    members[:, 0] = [[1.0 if i % 2 else 3.0, 0.5] for i in range(8)]
    none = np.zeros((8, 0))
    res = member_probe(none[:4], members[:4], none[4:], members[4:], ridge=1e-8)
    assert res["median_depth_m"] == pytest.approx(1.0) and res["median_lateral_m"] == pytest.approx(0.0)
    assert res["median_m"] == pytest.approx(1.0) and res["scored"] == 4
    # its own pixel row carries the depth exactly (a linear map of it): the pixel probe recovers it
    px = np.zeros((8, 2, 2))
    px[:, 0, 1] = 40.0 - 5.0 * members[:, 0, 0]
    px[:, 1] = np.nan
    res = pixel_probe(px[:4], members[:4], px[4:], members[4:], ridge=1e-8)
    assert res["median_m"] < 1e-6 and res["scored"] == 4


def test_mlp_probe_reads_depth_from_a_torso_row_where_a_linear_map_cannot() -> None:
    # a pinhole camera 0.25 m below the torso plane: row offset 50 * 0.25 / depth, column 50 * lateral / depth
    rng = np.random.default_rng(0)
    depth, lateral = rng.uniform(1.0, 5.0, 3000), rng.uniform(-1.0, 1.0, 3000)
    members = np.full((3000, 1, 2), np.nan)
    members[:, 0] = np.column_stack([depth, lateral])
    px = np.column_stack([32.0 + 50.0 * lateral / depth, 32.0 - 12.5 / depth])[:, None]
    lin = pixel_probe(px[:2400], members[:2400], px[2400:], members[2400:])
    mlp = pixel_probe(px[:2400], members[:2400], px[2400:], members[2400:], reader="mlp")
    assert lin["median_depth_m"] > 0.2 and mlp["median_m"] < 0.1 and mlp["scored"] == 600
    small = [fit_predict_mlp(px[:300, 0], members[:300, 0], px[300:310, 0], epochs=2) for _ in range(2)]
    assert np.array_equal(small[0], small[1])  # seeded
    with pytest.raises(ValueError, match="reader 'knn'"):
        pixel_probe(px[:2400], members[:2400], px[2400:], members[2400:], reader="knn")


def test_keypoint_precision_feet_tolerate_noise_that_torso_rows_do_not() -> None:
    from ssbl_pb.bench.camera import keypoint_precision

    rng = np.random.default_rng(1)
    n = 1200
    depth, lateral = rng.uniform(1.0, 5.0, n), rng.uniform(-0.4, 0.4, n) * rng.uniform(1.0, 5.0, n) / 2
    cam = sim_camera(RobotParams(), 64, 64)
    members = np.column_stack([depth, lateral])[:, None].astype(np.float32)
    torso = cam.robot_to_pixel(np.column_stack([depth, lateral, np.full(n, 1.4)]))[:, None].astype(np.float32)
    frames = {"frames": np.zeros((n, 64, 64, 3), np.uint8), "episode": np.repeat(np.arange(20), 60),
              "members_rel": members, "members_px": torso}
    res = keypoint_precision(frames, noise_px=(0.0, 2.0))
    # a linear map reads any affine image of the pixels alike: the foot row is one of the torso row (pitch 0)
    assert res["feet_linear_noise0"]["median_m"] == pytest.approx(res["torso_linear_noise0"]["median_m"], rel=1e-4)
    # two pixels of noise: the torso row (0.25 m above the camera) loses depth, the foot row (1.15 m below) keeps it
    assert res["feet_mlp_noise2"]["median_m"] < 0.5 * res["torso_mlp_noise2"]["median_m"], res
    # feet in view: row cy + f 1.15 / depth below the image's last row (cy = 31, f = 32 / tan(28.15 deg))
    held = np.repeat(np.arange(20), 60) % 10 == 9
    held &= np.isin(np.arange(n), np.arange(n)[np.isin(np.arange(n) % 60, [0, 59])], invert=True)
    f = 32.0 / np.tan(np.radians(56.3 / 2))
    u = 32.0 - f * lateral / depth
    want = np.mean(((31.0 + f * 1.15 / depth) < 64) & (u >= 0) & (u < 64), where=held)
    assert res["feet_in_image"] == pytest.approx(want, abs=0.02)
    # frames seen through the paper's 26.5 deg camera: the feet are projected through that one
    narrow = keypoint_precision(frames | {"camera_hfov": np.float32(26.5)}, noise_px=(0.0,))
    f = 32.0 / np.tan(np.radians(26.5 / 2))
    u = 32.0 - f * lateral / depth
    want = np.mean(((31.0 + f * 1.15 / depth) < 64) & (u >= 0) & (u < 64), where=held)
    assert narrow["feet_in_image"] == pytest.approx(want, abs=0.02) and want < 0.5 * res["feet_in_image"]


def test_pets_person_boxes_stand_on_their_ground_points(shared_data) -> None:
    from ssbl_pb.perception.autoencoding.pets_saev import ground_truth_positions, person_boxes
    from ssbl_pb.perception.datasets.pets import foot_points, load_ground_truth
    from ssbl_pb.perception.datasets.tsai import TsaiCamera

    pets = shared_data / "video" / "pets2009_s2l1"
    cam = TsaiCamera.from_xml(pets / "View_001_tsai_calibration.xml")
    xy = np.array([[5.0, 10.0], [15.0, 3.0]])
    boxes = person_boxes(cam, xy)
    assert np.allclose(cam.image_to_ground(foot_points(boxes[:, :4])), xy, atol=1e-6)
    assert np.all(boxes[:, 3] > 0) and np.allclose(boxes[:, 2], 0.42 * boxes[:, 3])
    gt = load_ground_truth(pets / "PETS2009-S2L1.xml")
    truth = ground_truth_positions(gt, cam, 3, 768, 576)
    first = gt[gt[:, 0] == 0]
    assert np.isfinite(truth[0, :, 0]).sum() <= len(first) and np.isfinite(truth[0, 0]).all()
