"""The shipped URDFs load with yourdfpy and PyBullet and have Pepper's real dimensions."""

import numpy as np
import pybullet as p
import pytest
import yourdfpy

from ssbl_pb.urdf import urdf_path


def test_pepper_link_tree_and_camera_frame():
    robot = yourdfpy.URDF.load(str(urdf_path("pepper")))
    assert {"base_link", "Head", "CameraTop_frame", "CameraTop_optical_frame"} <= set(robot.link_map)
    T = robot.get_transform("CameraTop_optical_frame", "base_link")
    assert T[2, 3] == pytest.approx(1.15, abs=0.01)
    assert T[0, 3] == pytest.approx(0.05, abs=0.01)
    # optical frame: z axis points forward (+x of the base)
    assert T[:3, 2] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)
    total_mass = sum(link.inertial.mass for link in robot.link_map.values() if link.inertial)
    assert 20 < total_mass < 35  # the real Pepper weighs 28 kg


def test_human_has_head_and_facing_marker():
    human = yourdfpy.URDF.load(str(urdf_path("human")))
    assert {"base_link", "torso", "head", "facing_marker"} <= set(human.link_map)
    T = human.get_transform("head", "base_link")
    assert T[2, 3] + 0.12 == pytest.approx(1.7, abs=0.03)


@pytest.mark.parametrize("name,height", [("pepper", 1.21), ("human", 1.70)])
def test_pybullet_loads_with_expected_height(name, height):
    c = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf_path(name)), useFixedBase=True, physicsClientId=c)
        top = max(p.getAABB(body, link, physicsClientId=c)[1][2]
                  for link in range(-1, p.getNumJoints(body, physicsClientId=c)))
        assert top == pytest.approx(height, abs=0.03)
    finally:
        p.disconnect(c)


def test_missing_urdf_names_the_file():
    with pytest.raises(FileNotFoundError, match="nope"):
        urdf_path("nope")


def test_camera_link_height_in_pybullet():
    c = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf_path("pepper")), useFixedBase=True, physicsClientId=c)
        names = [p.getJointInfo(body, j, physicsClientId=c)[12].decode() for j in range(p.getNumJoints(body,
                                                                                                      physicsClientId=c))]
        idx = names.index("CameraTop_optical_frame")
        pos = p.getLinkState(body, idx, physicsClientId=c)[4]
        assert np.allclose(pos, [0.05, 0.0, 1.15], atol=0.01)
    finally:
        p.disconnect(c)
