"""The observation model measured from deploy runs (bench/observation_fit.py): synthetic samples with known
noise, misses and visibility, and the tool's errors."""

from __future__ import annotations

import numpy as np
import pytest

from ssbl_pb.bench.observation_fit import fit, plot, robust_std, threshold
from ssbl_pb.bench.perception_errors import Samples
from ssbl_pb.errors import UserError


def test_the_robust_std_is_1_4826_times_the_median_absolute_deviation():
    assert robust_std([1.0, 2.0, 3.0, 4.0, 100.0, np.nan]) == pytest.approx(1.4826)  # deviations 2, 1, 0, 1, 97
    assert np.isnan(robust_std([np.nan]))


def test_the_threshold_is_where_the_detected_share_falls_below_the_floor():
    bins = [{"lo": lo, "hi": hi, "n": 100, "seen_rate": r}
            for lo, hi, r in ((0.0, 0.5, 0.1), (0.5, 0.8, 0.3), (0.8, 0.95, 0.6), (0.95, 1.01, 0.9))]
    # between the middles of the bins either side: 0.65 at 0.3, 0.875 at 0.6
    assert threshold(bins, 0.45, rising=True) == pytest.approx(0.65 + 0.5 * 0.225)
    falling = [{"lo": lo, "hi": hi, "n": n, "seen_rate": r}
               for lo, hi, n, r in ((0.0, 0.25, 100, 0.9), (0.25, 0.5, 100, 0.8), (0.5, 0.75, 10, 0.1),
                                    (0.75, 1.0, 100, 0.2))]
    # the 10-tick bin does not count: between 0.375 at 0.8 and 0.875 at 0.2
    assert threshold(falling, 0.45, rising=False) == pytest.approx(0.375 + 0.35 / 0.6 * 0.5)
    assert threshold(bins[-1:], 0.45, rising=True) == 0.0 and threshold(falling[:1], 0.95, rising=False) == 0.0


def test_fit_recovers_the_noise_misses_and_visibility_it_was_drawn_with(tmp_path):
    rng = np.random.default_rng(0)
    n = 20000
    r = rng.uniform(1.0, 6.0, n)
    hidden = np.where(rng.random(n) < 0.3, rng.uniform(0.0, 1.0, n), 0.0)
    in_image = np.where(rng.random(n) < 0.3, rng.uniform(0.0, 1.0, n), 1.0)
    # detected: 90 % in plain sight; never when more than 0.6 hidden or less than 0.9 in the image
    seen = (rng.random(n) < 0.9) & (hidden <= 0.6) & (in_image >= 0.9)
    sd = np.where(r < 3.0, 0.01, 0.05 * r)
    front = rng.random(n) < 0.5
    s = Samples(range_m=r.tolist(), seen=seen.tolist(), remembered=[False] * n,
                range_err=np.where(seen, sd * rng.standard_normal(n), np.nan).tolist(),
                bearing_err=np.where(seen, 1.0 * rng.standard_normal(n), np.nan).tolist(),
                facing_err=np.where(front, 10.0, 30.0) * rng.standard_normal(n) + 180.0 * (rng.random(n) < 0.05),
                front=front.tolist(), hidden=hidden.tolist(), in_image=in_image.tolist(),
                tracks=[1] * (n - 100) + [2] * 100, false_tracks=[0, 1, 0, 1])
    result = fit(s)
    f = result["fields"]
    assert plot(result, tmp_path / "fit.png").stat().st_size > 10_000
    assert result["evidence"]["duplicated"] == pytest.approx(100 / n) and result["evidence"][
        "false_tracks_per_tick"] == 0.5
    assert f["laser_std_m"] == pytest.approx(0.01, rel=0.05)
    assert f["range_std_per_m"] == pytest.approx(0.05, rel=0.05) and f["range_std_m"] == 0.0
    assert f["bearing_std_deg"] == pytest.approx(1.0, rel=0.05)
    assert f["miss_prob"] == pytest.approx(0.1, abs=0.01)
    # drawn as steps at 0.9 and 0.6: interpolated between the bins' middles either side
    assert f["min_visible"] == pytest.approx(0.9, abs=0.02) and f["hidden_fraction"] == pytest.approx(0.58, abs=0.03)
    assert f["facing_std_deg"] == pytest.approx(10.0, rel=0.06) and f["facing_back_std_deg"] == pytest.approx(
        30.0, rel=0.06)
    assert f["facing_flip_prob"] == pytest.approx(0.05 + 0.95 * 0.5 * 0.0027, abs=0.006)  # + the back's > 3 sigma


def test_the_tool_names_a_folder_without_runs(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "tools" / "fit_observation.py"
    spec = importlib.util.spec_from_file_location("fit_observation", path)
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    (tmp_path / "run00").mkdir()
    with pytest.raises(UserError, match="run00.*expected a run folder"):
        tool.run_folders([tmp_path / "run00"])
    (tmp_path / "run01").mkdir()
    (tmp_path / "run01" / "virtual_pepper.jsonl").write_text("")
    assert tool.run_folders([tmp_path]) == [tmp_path / "run01"]
