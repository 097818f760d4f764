"""Tsai camera (PETS calibration): loading, projection round trips, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from ssbl_pb.perception.datasets.tsai import CalibrationError, TsaiCamera, euler_to_matrix

PETS = "video/pets2009_s2l1/View_001_tsai_calibration.xml"

SYNTH = """<?xml version="1.0"?>
<Camera name="synthetic">
  <Geometry width="640" height="480" ncx="640" nfx="640" dx="0.005" dy="0.005" dpx="0.005" dpy="0.005"/>
  <Intrinsic focal="4.0" kappa1="{k}" cx="320" cy="240" sx="1.0"/>
  <Extrinsic tx="0" ty="0" tz="8000" rx="2.2" ry="0.1" rz="-0.3"/>
</Camera>
"""


def write(tmp_path, text, name="cam.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_rotation_is_orthonormal():
    r = euler_to_matrix(2.04, -0.89, -0.43)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


@pytest.mark.parametrize("kappa", [0.0, 5e-3, -5e-3])
def test_synthetic_round_trip(tmp_path, kappa):
    cam = TsaiCamera.from_xml(write(tmp_path, SYNTH.format(k=kappa)))
    rng = np.random.default_rng(0)
    uv = rng.uniform([20, 260], [620, 470], size=(200, 2))
    g = cam.image_to_ground(uv)
    assert np.all(np.isfinite(g))
    assert np.abs(cam.world_to_image(g) - uv).max() < 1e-6
    # and the other way: ground -> image -> ground, at scale 0.5 too
    half = cam.scaled(0.5)
    back = half.image_to_ground(half.world_to_image(g))
    assert np.abs(back - g).max() < 1e-6


def test_pets_calibration_against_ground_truth_box(shared_data):
    cam = TsaiCamera.from_xml(shared_data / PETS)
    assert cam.width == 768 and cam.height == 576
    # camera about 7 m above the square
    assert cam.centre_m[2] == pytest.approx(7.07, abs=0.05)
    # frame 0, id 15: box xc=274.49 yc=263.00 h=88.70 -> a 1.75 m person's head lands at the box top
    foot = np.array([274.49, 263.0 + 88.70 / 2])
    g = cam.image_to_ground(foot)
    head = cam.world_to_image(np.array([g[0], g[1], 1.75]))
    assert head[1] == pytest.approx(263.0 - 88.70 / 2, abs=3.0)
    assert np.abs(cam.world_to_image(g) - foot).max() < 1e-6


def test_missing_field_names_file_and_field(tmp_path):
    bad = write(tmp_path, SYNTH.format(k=0).replace(' focal="4.0"', ""))
    with pytest.raises(CalibrationError, match=r"cam\.xml.*Intrinsic.*focal"):
        TsaiCamera.from_xml(bad)


def test_missing_element_and_not_xml(tmp_path):
    with pytest.raises(CalibrationError, match="Extrinsic"):
        TsaiCamera.from_xml(write(tmp_path, "<Camera><Geometry/><Intrinsic/></Camera>"))
    with pytest.raises(CalibrationError, match="not valid XML"):
        TsaiCamera.from_xml(write(tmp_path, "fx: 1\n", "cam.yaml"))
    with pytest.raises(CalibrationError, match="not found"):
        TsaiCamera.from_xml(tmp_path / "nope.xml")
