"""The sim camera and detectors on TinyRenderer frames: boxes land where the members are."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.bench.sim_tracking import proxy_geometry
from ssbl_pb.env.view.world import World
from ssbl_pb.perception.camera import sim_camera
from ssbl_pb.perception.detection.detectors import ColourDetector, SimDetector, mask_boxes
from ssbl_pb.perception.detection.ground import boxes_to_ground
from ssbl_pb.urdf import HUMAN_COLOURS


@pytest.fixture(scope="module")
def scene():
    world = World()
    world.reset(np.random.default_rng(3), n_humans=3)
    # put the robot 3.5 m from the group centre, facing it
    c = world.group.centre0
    world.base.reset(np.array([c[0] - 3.5, c[1], 0.0]))
    world._synced = False
    yield world
    world.close()


def local_positions(world):
    x, y, yaw = world.robot_pose
    c, s = math.cos(yaw), math.sin(yaw)
    d = world.group.pos - np.array([x, y])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_mask_boxes():
    m = np.zeros((10, 12), int)
    m[2:5, 3:7] = 4
    b = mask_boxes(m, [4, 9])
    assert b[0].tolist() == [3, 2, 4, 3, 1] and np.isnan(b[1, 0])


def test_seg_boxes_give_member_positions(scene):
    cam = sim_camera(scene.robot_params, 320, 240)
    rgb, seg = scene.render_first_person(320, 240, segmentation=True)
    boxes, members = SimDetector(scene.human_ids).with_index(seg)
    assert len(members) >= 2
    truth = local_positions(scene)[members]
    est = boxes_to_ground(cam, boxes, proxy_geometry(scene))
    ok = ~np.isnan(est[:, 0]) & (boxes[:, 0] > 0) & (boxes[:, 0] + boxes[:, 2] < 320)
    assert ok.sum() >= 2
    err = np.hypot(*(est[ok] - truth[ok]).T)
    assert np.median(err) < 0.15, err
    # the sim pinhole projects each member's floor point inside (or just below) its box, horizontally
    uv = cam.ground_to_pixel(truth[ok])
    b = boxes[ok]
    assert np.all((uv[:, 0] > b[:, 0] - 3) & (uv[:, 0] < b[:, 0] + b[:, 2] + 3))


def test_colour_detector_matches_seg(scene):
    rgb, seg = scene.render_first_person(320, 240, segmentation=True)
    seg_boxes, _ = SimDetector(scene.human_ids).with_index(seg)
    col = ColourDetector(HUMAN_COLOURS)(rgb)
    assert abs(len(col) - len(seg_boxes)) <= 1
    # each torso box lies inside a whole-body box
    for b in col:
        inside = ((b[0] >= seg_boxes[:, 0] - 2) & (b[0] + b[2] <= seg_boxes[:, 0] + seg_boxes[:, 2] + 2) &
                  (b[1] >= seg_boxes[:, 1] - 2) & (b[1] + b[3] <= seg_boxes[:, 1] + seg_boxes[:, 3] + 2))
        assert inside.any()


def test_seg_detector_needs_mask(scene):
    rgb, _ = scene.render_first_person(64, 48)
    with pytest.raises(ValueError, match="segmentation"):
        SimDetector(scene.human_ids)((rgb, None))


def test_short_sim_evaluation():
    from ssbl_pb.bench.sim_tracking import SimEvalParams, evaluate_sim

    res = evaluate_sim(SimEvalParams(episodes=1, steps=40, width=160, height=120, seed=1))
    assert res["scored"] > 20
    assert res["median_err_m"] < 0.2
    assert res["coverage"] > 0.5
    with pytest.raises(ValueError, match="detector"):
        evaluate_sim(SimEvalParams(detector="hog"))
