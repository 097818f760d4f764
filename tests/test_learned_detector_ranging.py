"""Head-and-shoulders ranging (perception.detection.ranging) on hand-computed geometry, the tracker's use of it, and the
feet-hidden painting (perception.datasets.occlusion)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.perception.datasets.occlusion import FeetHidden, hide_lower_bodies
from ssbl_pb.perception.detection.ranging import FEET, HEAD, RangingParams, head_ground, implied_height, range_boxes

F, CX, CY, HC = 300.0, 160.0, 120.0, 1.15  # focal (px), principal point, camera height (m)
P = RangingParams(person_height=1.76, height_std=0.08, box_width=0.61, width_rel_std=0.25)


class Level:
    """A pinhole camera at (0, 0, HC) looking along +x, level: u = CX - F y / x, v = CY - F (z - HC) / x."""

    centre_m = np.array([0.0, 0.0, HC])

    def world_to_image(self, xyz: np.ndarray) -> np.ndarray:
        xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
        return np.column_stack([CX - F * xyz[:, 1] / xyz[:, 0], CY - F * (xyz[:, 2] - HC) / xyz[:, 0]])

    def image_to_plane(self, uv: np.ndarray, z: float) -> np.ndarray:
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        x = F * (z - HC) / (CY - uv[:, 1])
        return np.column_stack([x, (CX - uv[:, 0]) * x / F])


def person_box(x: float, y: float, height: float = 1.76, width: float = 0.61, keep: float = 1.0) -> np.ndarray:
    """The box of a person at (x, y) seen by ``Level``: head top at ``height``, ``keep`` of it from the top; its
    width that of ``width`` m across the line of sight at half the height."""
    u = CX - F * y / x
    top, foot = CY - F * (height - HC) / x, CY + F * HC / x
    side = np.array([-y, x]) / np.hypot(x, y) * width / 2
    ends = [Level().world_to_image(np.array([[x + s * side[0], y + s * side[1], height / 2]]))[0, 0] for s in (-1, 1)]
    w = abs(ends[1] - ends[0])
    return np.array([u - w / 2, top, w, keep * (foot - top)])


def test_head_cue_by_hand():
    # 4 m ahead: head top at v = 120 - 300 * 0.61 / 4 = 74.25, box 45.75 px wide: both cues say 4 m
    b = person_box(4.0, 0.0)
    assert b[1] == pytest.approx(74.25) and b[2] == pytest.approx(45.75)
    xy, cov = head_ground(Level(), b[None], P)
    np.testing.assert_allclose(xy, [[4.0, 0.0]], atol=1e-3)
    # off to the side: the same range along the line of sight
    xy, _ = head_ground(Level(), person_box(3.0, 1.0)[None], P)
    np.testing.assert_allclose(xy, [[3.0, 1.0]], atol=1e-3)


def test_head_and_width_fused_by_their_variances():
    # the box half as wide: the width says 8 m, the head row 4 m. Head: dx/dz = F / (CY - v) = 300 / 45.75, so
    # the height prior's 0.08 m is 0.5246 m of range (variance 0.2752); width: (0.25 * 8)^2 = 4
    b = person_box(4.0, 0.0)
    b[0] += b[2] / 4
    b[2] /= 2
    var_a, var_b = (0.08 * 300 / 45.75) ** 2, (0.25 * 8) ** 2
    r = (var_b * 4 + var_a * 8) / (var_a + var_b)
    xy, cov = head_ground(Level(), b[None], P)
    np.testing.assert_allclose(xy, [[r, 0.0]], atol=1e-3)
    assert r == pytest.approx(4.2575, abs=1e-3)
    # the along-sight variance is the fused one (plus the pixel noise through the Jacobian)
    assert cov[0, 0, 0] == pytest.approx(var_a * var_b / (var_a + var_b), rel=0.2)


def test_cue_choice_feet_head_and_cut():
    geom = Level()
    whole = person_box(4.0, 0.5)  # feet at v = 120 + 300 * 1.15 / 4 = 206.25, inside a 240 px image
    hips = person_box(4.0, -0.5, keep=0.55)  # lower body hidden: the box ends at the hips
    xy, cov, cue = range_boxes(geom, np.stack([whole, hips]), 240, P)
    assert list(cue) == [FEET, HEAD]
    np.testing.assert_allclose(xy, [[4.0, 0.5], [4.0, -0.5]], atol=1e-3)
    # the hips box (bottom at v = 74.25 + 0.55 * 132 = 146.85), ranged from its bottom as if feet: 345 / 26.85 =
    # 12.85 m away, where 1 m is 23.35 px and the box's 72.6 px imply a 3.1 m person (above max_body_height)
    foot = geom.image_to_plane(np.array([[CX, hips[1] + hips[3]]]), 0.0)
    assert foot[0, 0] == pytest.approx(12.849, abs=1e-3)
    assert implied_height(geom, foot, [hips[1]])[0] == pytest.approx(3.109, abs=1e-3)
    # the same whole person in a 200 px image: the box's bottom is the image's, ranged from the head
    cut = whole.copy()
    cut[3] = 200 - cut[1]
    _, _, cue = range_boxes(geom, cut[None], 200, P)
    assert list(cue) == [HEAD]
    # the tracker trusts the head cue less along the line of sight than the feet at the same place
    assert cov[1, 0, 0] > cov[0, 0, 0]


def test_a_box_too_wide_for_a_whole_person_is_ranged_from_the_head():
    geom = Level()
    whole = person_box(4.0, 0.0)  # 45.75 x 132 px: width / height 0.347
    # cut at 80 %: bottom at v = 74.25 + 105.6 = 179.85, as feet 345 / 59.85 = 5.764 m away, where 1 m is
    # 52.05 px: the 105.6 px imply a 2.03 m person, plausible, so only the box's shape (0.433) tells it is cut
    knees = person_box(4.0, 0.0, keep=0.8)
    assert knees[2] / knees[3] == pytest.approx(0.4332, abs=1e-4)
    _, _, cue = range_boxes(geom, np.stack([whole, knees]), 240, P)
    assert list(cue) == [FEET, FEET]
    xy, _, cue = range_boxes(geom, np.stack([whole, knees]), 240, dataclasses.replace(P, max_aspect=0.4))
    assert list(cue) == [FEET, HEAD]
    np.testing.assert_allclose(xy, [[4.0, 0.0], [4.0, 0.0]], atol=1e-3)


def test_ground_tracker_ranges_cut_boxes_from_the_head():
    calib = Path(__file__).resolve().parents[2] / "shared/data/video/pets2009_s2l1/View_001_tsai_calibration.xml"
    if not calib.is_file():
        pytest.skip(f"PETS calibration not found: {calib}")
    from ssbl_pb.perception.datasets.tsai import TsaiCamera
    from ssbl_pb.perception.tracking.pipeline import BoxParams, GroundTracker

    cam = TsaiCamera.from_xml(calib)
    truth = np.array([2.0, 5.0])
    foot = cam.world_to_image(np.array([*truth, 0.0]))
    head = cam.world_to_image(np.array([*truth, 1.76]))
    h = foot[1] - head[1]
    box = np.array([[foot[0] - 0.2 * h, head[1], 0.4 * h, 0.55 * h, 1.0]])  # lower body cut away
    for ranging, far in ((False, True), (True, False)):
        gt = GroundTracker(cam, box=BoxParams(head_ranging=ranging, pixel_noise=0.05))
        gt.step(box, 0.1)
        z = gt.tracker.tracks[0].kf.x[:2].ravel() if gt.tracker.tracks else None
        assert z is not None
        assert (np.hypot(*(z - truth)) > 1.0) == far  # the hips taken for feet land metres away
        assert list(gt.cues) == ([HEAD] if ranging else [FEET])


def test_feet_hidden_painting():
    frame = np.full((10, 8, 3), 200, np.uint8)
    bg = np.zeros_like(frame)
    out = hide_lower_bodies(frame, np.array([[2.0, 0.0, 4.0, 10.0]]), bg, keep=0.55)
    assert (out[:5] == 200).all()  # rows 0-4 kept (0.55 * 10 = 5.5 -> painted from row 5)
    assert (out[5:, 2:6] == 0).all() and (out[5:, :2] == 200).all() and (out[5:, 6:] == 200).all()
    assert (frame == 200).all()  # a copy
    painter = FeetHidden(np.array([[3, 1, 2.0, 0.0, 4.0, 10.0]]), bg)
    assert (painter(3, frame) == out).all() and (painter(4, frame) == frame).all()
