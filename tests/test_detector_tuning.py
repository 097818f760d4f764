"""Choosing the learned detector's thresholds (tools/bench_tracking.py --tune): the coordinate descent with the
feet-hidden frames in its score, the cached detector output standing in for the online detector, the ranging
cues' own measurement noise, and the tool's errors."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest

from ssbl_pb.errors import UserError
from ssbl_pb.perception.detection.learned import SsdDetector, SsdParams
from ssbl_pb.perception.detection.ranging import HEAD, RangingParams
from ssbl_pb.perception.tracking.pipeline import BoxParams, GroundTracker
from ssbl_pb.perception.tracking.tracker import TrackerParams
from ssbl_pb.perception.tracking.tuning import PipelineParams, cache_raw, select_cached, tune

ROOT = Path(__file__).resolve().parents[1]
PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"
CALIB = PETS / "View_001_tsai_calibration.xml"
GT = PETS / "PETS2009-S2L1.xml"
FRAME = PETS / "img1" / "000001.jpg"
needs_pets = pytest.mark.skipif(not (CALIB.is_file() and GT.is_file()), reason=f"PETS data not found under {PETS}")

EXACT = SsdParams(score_threshold=0.1, shrink_x=0.0, shrink_top=0.0, shrink_bottom=0.0)  # boxes kept as they are


def bench_tool():
    spec = importlib.util.spec_from_file_location("_bench_tracking", ROOT / "tools" / "bench_tracking.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@needs_pets
def test_tune_picks_the_threshold_that_drops_false_boxes_and_adds_the_hidden_score():
    from ssbl_pb.perception.datasets.pets import load_ground_truth
    from ssbl_pb.perception.datasets.tsai import TsaiCamera

    cam, gt = TsaiCamera.from_xml(CALIB), load_ground_truth(GT)
    frames = range(0, 15)
    # every GT person found (score 0.9) plus a ghost at a fixed empty spot (score 0.3) in every frame
    ghost = np.array([[20.0, 300.0, 40.0, 100.0, 0.3]])
    raw = {f: np.vstack([np.column_stack([gt[gt[:, 0] == f, 2:6], np.full((gt[:, 0] == f).sum(), 0.9)]), ghost])
           for f in frames}
    init = PipelineParams(detector="ssd", ssd=EXACT, trk=TrackerParams(birth_hits=2, meas_std=0.1))
    grid = {"ssd.score_threshold": [0.1, 0.5]}
    best, res, log = tune(raw, gt, cam, 1 / 7, 0, 15, init, rounds=2, grid=grid)
    assert best.ssd.score_threshold == 0.5 and res["num_false_positives"] == 0 and res["mota"] > 0.9
    # round 1 tries 0.5 (better), round 2 tries 0.1 again (worse): no change, so it stops
    assert [e["value"] for e in log] == [None, 0.5, 0.1]
    assert log[1]["score"] > log[0]["score"] == pytest.approx(log[2]["score"])
    # the same frames once more as ``extra``: each trial's score is the sum of its two parts
    _, res2, log2 = tune(raw, gt, cam, 1 / 7, 0, 15, init, rounds=2, grid=grid, extra=(raw,))
    assert res2 == res
    for a, b in zip(log, log2, strict=True):
        assert b["parts"] == pytest.approx([a["score"], a["score"]]) and b["score"] == pytest.approx(2 * a["score"])


@pytest.mark.skipif(not FRAME.is_file(), reason=f"PETS frame not found: {FRAME}")
def test_cached_detector_output_selects_to_the_online_boxes():
    cv2.setNumThreads(1)
    crop = np.ascontiguousarray(cv2.imread(str(FRAME))[100:388, 200:584])
    pp = PipelineParams(detector="ssd", ssd=SsdParams(score_threshold=0.2, input_size=(320, 240)))
    raw = cache_raw([(7, crop)], pp)
    assert list(raw) == [7] and (raw[7][:, 4] >= pp.ssd.raw_threshold).all()
    online = SsdDetector(pp.ssd)(crop)
    assert len(online) >= 2  # two walkers in this crop
    np.testing.assert_allclose(select_cached(raw[7], pp), online)
    with pytest.raises(UserError, match="detect_raw"):
        cache_raw([(0, crop)], PipelineParams())


@needs_pets
def test_each_ranging_cue_has_its_own_measurement_noise():
    """A new track's position covariance is the first detection's: a head-ranged box's follows ``rng.pixel_noise``
    (times the box's width), a foot-ranged box's ``box.pixel_noise`` (times its height)."""
    from ssbl_pb.perception.datasets.tsai import TsaiCamera

    cam = TsaiCamera.from_xml(CALIB)
    truth = np.array([2.0, 5.0])
    foot = cam.world_to_image(np.array([*truth, 0.0]))
    head = cam.world_to_image(np.array([*truth, 1.76]))
    h = foot[1] - head[1]
    whole = np.array([[foot[0] - 0.2 * h, head[1], 0.4 * h, h, 1.0]])
    cut = whole * [1, 1, 1, 0.55, 1]  # lower body gone: ranged from the head

    def first_var(box: np.ndarray, feet_noise: float, head_noise: float) -> tuple[float, int]:
        g = GroundTracker(cam, TrackerParams(meas_std=0.01), BoxParams(head_ranging=True, pixel_noise=feet_noise),
                          RangingParams(pixel_noise=head_noise))
        g.step(box, 0.1)
        return float(np.trace(g.tracker.tracks[0].kf.P[:2, :2])), int(g.cues[0])

    (hv1, c1), (hv2, _), (hv3, _) = (first_var(cut, 0.05, 0.05), first_var(cut, 0.2, 0.05),
                                     first_var(cut, 0.05, 0.2))
    assert c1 == HEAD and hv2 == pytest.approx(hv1) and hv3 > hv1
    (fv1, c2), (fv2, _), (fv3, _) = (first_var(whole, 0.05, 0.05), first_var(whole, 0.2, 0.05),
                                     first_var(whole, 0.05, 0.2))
    assert c2 != HEAD and fv3 == pytest.approx(fv1)
    # the foot point's variance is the pixel noise squared through the Jacobian (+ the floor): x 16 at 4x noise
    assert fv2 - 2 * 0.01 ** 2 == pytest.approx(16 * (fv1 - 2 * 0.01 ** 2), rel=1e-6)


def test_params_carry_the_ranging_priors():
    p = PipelineParams(detector="ssd", rng=RangingParams(pixel_noise=0.2, height_std=0.12))
    assert PipelineParams.from_dict(p.to_dict()) == p
    d = p.to_dict()
    del d["rng"]  # files written before the ranging priors were tuned
    assert PipelineParams.from_dict(d).rng == RangingParams()
    assert p.with_value("rng.width_rel_std", 0.4).rng.width_rel_std == 0.4


def test_tune_option_errors():
    from ssbl_pb.bench.tracking import parse_size

    tool = bench_tool()
    assert parse_size("400x300") == (400, 300)
    with pytest.raises(UserError, match="--input-size '10x10': expected both sides >= 32"):
        tool.main(["--tune", "--input-size", "10x10"])
    with pytest.raises(UserError, match="--input-size 'big': expected WxH"):
        tool.main(["--tune", "--input-size", "big"])
    with pytest.raises(UserError, match="only for --detector ssd"):
        tool.main(["--tune", "--detector", "hog", "--input-size", "400x300"])
    with pytest.raises(UserError, match="--rounds 0"):
        tool.main(["--tune", "--rounds", "0"])


def test_tune_names_missing_data(tmp_path, capsys):
    assert bench_tool().main(["--tune", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "out")]) == 2
    assert "none/vtest.avi: not found" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_bench_deploy_hands_its_detector_to_deploy(monkeypatch, tmp_path):
    """tools/bench_deploy.py --detector reaches deploy's command line (the learned detector against the virtual
    Pepper); a name deploy does not know is refused before anything runs."""
    import contextlib

    from ssbl_pb.bench import deploy as bench

    seen = []

    @contextlib.contextmanager
    def pepper(*_args, **_kw):
        yield None, "tcp://127.0.0.1:1"

    def deploy(url, folder, policy, *extra):
        seen.append(extra)
        raise RuntimeError("stop here")

    monkeypatch.setattr(bench, "virtual_pepper", pepper)
    monkeypatch.setattr(bench, "start_deploy", deploy)
    with pytest.raises(RuntimeError, match="stop here"):
        bench.run_approach(tmp_path / "run", 0, detector="ssd", room_map=False)
    assert seen and list(seen[0][seen[0].index("--detector"):][:2]) == ["--detector", "ssd"]
    spec = importlib.util.spec_from_file_location("_bench_deploy", ROOT / "tools" / "bench_deploy.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    with pytest.raises(UserError, match="argument --detector: invalid choice: 'yolo'"):
        tool.main(["--detector", "yolo", "--out", str(tmp_path / "bd")])
    assert not (tmp_path / "bd").exists()


def test_the_learned_detectors_grid_searches_birth_scores_on_the_networks_scale():
    # HOG's birth margins (0.6-1.5) once replaced the network's list: MoveNet's 0.1-0.45 scores bore no track
    from ssbl_pb.perception.tracking.tuning import GRID, SSD_GRID

    assert max(GRID["trk.birth_score"]) > 1.0
    assert all(0.0 < v <= 1.0 for v in SSD_GRID["trk.birth_score"]) and min(SSD_GRID["trk.birth_score"]) <= 0.2
