"""Pipeline pieces on synthetic inputs: shrink/select/NMS, ground covariance, boxes drawn from tracks."""

from __future__ import annotations

import numpy as np
import pytest

from ssbl_pb.perception.datasets.tsai import TsaiCamera
from ssbl_pb.perception.detection.detectors import HogParams, box_fractions, nms, shrink_windows
from ssbl_pb.perception.tracking.pipeline import BoxParams, GroundTracker, ground_covariance, select
from ssbl_pb.perception.tracking.tracker import TrackerParams
from ssbl_pb.perception.tracking.tuning import PipelineParams, keep_scales

CAM = """<?xml version="1.0"?>
<Camera name="c"><Geometry width="768" height="576" dpx="0.005127" dpy="0.00465"/>
<Intrinsic focal="5.555" kappa1="0.00511" cx="324.2" cy="282.6" sx="1.0938"/>
<Extrinsic tx="828.7" ty="-3175.5" tz="35469.3" rx="2.0405" ry="-0.8934" rz="-0.4306"/></Camera>
"""  # the PETS View_001 numbers (camera 7 m up)


@pytest.fixture
def cam(tmp_path):
    p = tmp_path / "cam.xml"
    p.write_text(CAM)
    return TsaiCamera.from_xml(p)


def test_shrink_and_select():
    p = HogParams(shrink_x=0.25, shrink_top=0.1, shrink_bottom=0.1, hit_threshold=0.5, fg_min=0.3, nms_iou=0.3)
    win = np.array([[100, 50, 64, 128, 1.0, 0.9], [102, 52, 64, 128, 0.8, 0.9],  # duplicate: NMS
                    [300, 50, 64, 128, 0.4, 0.9],  # below the threshold
                    [500, 50, 64, 128, 2.0, 0.1]])  # static background
    assert shrink_windows(win[:1, :5], p)[0].tolist() == pytest.approx([116, 62.8, 32, 102.4, 1.0])
    out = select(win, p)
    assert len(out) == 1 and out[0, 0] == pytest.approx(116)


def test_nms_and_fractions():
    boxes = np.array([[0, 0, 10, 10, 0.5], [1, 1, 10, 10, 0.9], [50, 50, 10, 10, 0.1]], dtype=float)
    kept = nms(boxes, 0.3)
    assert kept[:, 4].tolist() == [0.9, 0.1]
    mask = np.zeros((100, 100), np.float32)
    mask[0:10, 0:5] = 1
    assert box_fractions(mask, boxes[:1]).tolist() == pytest.approx([0.5])


def test_keep_scales():
    raw = np.array([[0, 0, 64 / s, 128 / s, 1, 1] for s in (0.8, 1.0, 1.45)])
    assert len(keep_scales(raw, (1.0, 1.45))) == 2


def test_ground_covariance_grows_with_range(cam):
    near, far = np.array([[384, 550]]), np.array([[384, 200]])
    c_near = ground_covariance(cam, near, np.array([2.0]))[0]
    c_far = ground_covariance(cam, far, np.array([2.0]))[0]
    assert np.trace(c_far) > 4 * np.trace(c_near)
    assert np.all(np.linalg.eigvalsh(c_far) > 0)


def test_ground_tracker_boxes_follow_a_walker(cam):
    """A 1.8 m person walking on the ground: boxes from the tracker keep one id and match the true box."""
    gt = GroundTracker(cam, TrackerParams(dt=0.1, birth_hits=2, meas_std=0.05), BoxParams(aspect=0.4))
    for k in range(30):
        xy = np.array([-8.0 + 0.12 * k, -8.0])
        foot = cam.world_to_image(np.array([*xy, 0.0]))
        head = cam.world_to_image(np.array([*xy, 1.8]))
        h = foot[1] - head[1]
        box = np.array([[foot[0] - 0.2 * h, head[1], 0.4 * h, h, 1.0]])
        out = gt.step(box, 0.1)
    assert [o[0] for o in out] == [1]
    _, bb, pos, vel = out[0]
    assert np.hypot(*(pos - xy)) < 0.05 and np.hypot(*(vel - [1.2, 0])) < 0.1
    assert bb[3] == pytest.approx(h, rel=0.03) and bb[1] == pytest.approx(head[1], abs=2)


def test_pipeline_params_round_trip():
    p = PipelineParams()
    assert PipelineParams.from_dict(p.to_dict()) == p
    assert p.with_value("trk.gate", 9.0).trk.gate == 9.0
