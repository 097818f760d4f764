"""A short real-data run: detector + tracker on the first PETS 2009 S2L1 frames, scored against the GT."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ssbl_pb.perception.datasets.pets import foot_points, load_ground_truth
from ssbl_pb.perception.datasets.scoring import evaluate
from ssbl_pb.perception.datasets.tsai import TsaiCamera
from ssbl_pb.perception.detection.detectors import HogDetector, HogParams, nms
from ssbl_pb.perception.tracking.pipeline import GroundTracker, HogFgDetector, read_frames
from ssbl_pb.perception.tracking.tuning import PipelineParams

FRAMES = 20


@pytest.fixture
def pets(shared_data):
    d = shared_data / "video" / "pets2009_s2l1"
    return d, TsaiCamera.from_xml(d / "View_001_tsai_calibration.xml"), load_ground_truth(d / "PETS2009-S2L1.xml")


def test_gt_foot_points_are_on_the_square(pets):
    _, cam, gt = pets
    xy = cam.image_to_ground(foot_points(gt[:, 2:6]))
    # the PETS tracking area is a few tens of metres across; nobody is behind the camera or kilometres away
    assert np.all(np.hypot(*(xy - cam.centre_m[:2]).T) < 60)
    assert np.ptp(xy[:, 0]) > 10 and np.ptp(xy[:, 1]) > 10
    # walking speed from the GT: about 1 m/s at PETS 2009's 7 frames/s (vtest.avi's header says 10)
    speeds = []
    for tid in np.unique(gt[:, 1]):
        p = cam.image_to_ground(foot_points(gt[gt[:, 1] == tid, 2:6]))
        speeds.append(np.median(np.hypot(*np.diff(p, axis=0).T)) * 7)
    assert 0.8 < np.median(speeds) < 1.2

def test_hog_finds_people_in_first_frame(pets):
    d, _, gt = pets
    frame = cv2.imread(str(d / "img1" / "000001.jpg"))
    boxes = HogDetector(HogParams(scales=(1.2, 1.45), hit_threshold=0.5, shrink_x=0.235, shrink_top=0.115,
                                  shrink_bottom=0.14))(frame)
    g = gt[gt[:, 0] == 0]
    hits = 0
    for row in g:
        cx, cy = row[2] + row[4] / 2, row[3] + row[5] / 2
        hits += bool(np.any((np.abs(boxes[:, 0] + boxes[:, 2] / 2 - cx) < 15) &
                            (np.abs(boxes[:, 1] + boxes[:, 3] / 2 - cy) < 20)))
    assert hits >= 2 and len(boxes) <= len(g) + 3
    assert len(nms(np.vstack([boxes, boxes]), 0.3)) == len(boxes)


def test_short_tracking_run(pets):
    d, cam, gt = pets
    pp = PipelineParams()
    det = HogFgDetector(pp.hog)
    trk = GroundTracker(cam, pp.trk, pp.box)
    rows = []
    for i, frame in read_frames(d / "vtest.avi", 0, FRAMES):
        for tid, bb, xy, _ in trk.step(det(frame), 1 / 7):
            rows.append((i, tid, *bb, *xy))
    res = evaluate(np.array(rows), gt, cam, 0, FRAMES)
    assert res["mota"] > 0.6, res
    assert res["idf1"] > 0.7, res
    assert res["num_switches"] == 0
    assert res["ground_err_median_m"] < 0.35


def test_track_and_eval_cli(pets, tmp_path):
    import json
    import subprocess
    import sys
    from pathlib import Path

    d, _, _ = pets
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "run"
    calib = str(d / "View_001_tsai_calibration.xml")
    r = subprocess.run([sys.executable, "tools/track.py", str(d / "vtest.avi"), "--calib", calib, "--out", str(out),
                        "--stop", "8", "--fps", "7", "--quiet"], cwd=root, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["overlay.mp4", "tracks_mot.txt", "tracks_world.csv"]
    mot = np.loadtxt(out / "tracks_mot.txt", delimiter=",", ndmin=2)
    assert mot.shape[1] == 10 and mot[:, 0].min() >= 1 and mot[:, 0].max() <= 8
    from ssbl_pb.perception.tracking.tracking_io import read_world

    world = read_world(out / "tracks_world.csv")  # facing_deg is empty where a track's facing is unknown
    assert len(world) == len(mot) and np.all(np.isfinite(world[:, :6]))
    cap = cv2.VideoCapture(str(out / "overlay.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 8
    r = subprocess.run([sys.executable, "tools/eval_tracking.py", "--tracks", str(out), "--gt",
                        str(d / "PETS2009-S2L1.xml"), "--calib", calib, "--range", "0:8"], cwd=root,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "metrics.json").read_text())["frames 0-7"]
    assert m["mota"] > 0.5 and m["num_switches"] == 0
    assert (out / "metrics.md").read_text().startswith("# Tracking")
