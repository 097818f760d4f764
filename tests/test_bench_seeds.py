"""Seeds of one recipe summarised: mean and spread by hand, the table, and a run that has not finished."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from ssbl_pb.bench.policies import seed_spread, spread_markdown
from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("bench_seeds", ROOT / "tools" / "bench_seeds.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _row(success: float, jerk: float) -> dict:
    return {"success_rate": success, "violation_rate": 0.0, "personal_zone_time_s": 3.0,
            "human_displacement_m": 0.07, "arrival_speed": 0.07, "mean_jerk": jerk}


def test_the_spread_over_seeds_is_their_mean_and_sample_std_by_hand():
    table = {"s1 (off)": {"mixed": _row(0.90, 0.25)}, "s2 (off)": {"mixed": _row(0.94, 0.27)},
             "s3 (off)": {"mixed": _row(0.98, 0.23)}}
    spread = seed_spread(table, ["s1", "s2", "s3"], ["off"], ["mixed"])
    s = spread["off"]["mixed"]["success_rate"]
    assert s["mean"] == pytest.approx(0.94) and s["std"] == pytest.approx(0.04)  # sqrt((.04^2 + 0 + .04^2) / 2)
    assert s["values"] == [0.90, 0.94, 0.98]
    assert spread["off"]["mixed"]["mean_jerk"]["std"] == pytest.approx(0.02)
    text = spread_markdown(spread, ["mixed"])
    assert "| success_rate | 94.0 % ± 4.0 |" in text and "| mean_jerk | 0.250 ± 0.020 |" in text


def test_a_recipe_that_has_not_finished_is_named_with_what_to_do(tmp_path):
    run = tmp_path / "vector_recipe_s3"
    run.mkdir()
    (run / "recipe.json").write_text(json.dumps({"final_model": str(run / "10_vector")}))
    with pytest.raises(UserError, match="has not finished: run it again"):
        _tool().final_model(run)
    (run / "10_vector").mkdir()
    (run / "10_vector" / "model.zip").write_bytes(b"")
    assert _tool().final_model(run) == str(run / "10_vector")
    with pytest.raises(UserError, match="expected a recipe's output"):
        _tool().final_model(tmp_path)
