"""tools/trace_episode.py: one episode step by step (ssbl_pb/analysis/trace.py)."""

import csv
import json
from pathlib import Path

from ssbl_pb.analysis.trace import reversals, side_swaps

ROOT = Path(__file__).resolve().parents[1]


def _rows(lefts, driven=None, sides=None):
    driven = driven or [1] * len(lefts)
    sides = sides or [""] * len(lefts)
    return [{"asked_left": a, "driven": d, "nearest_member_side": s}
            for a, d, s in zip(lefts, driven, sides, strict=True)]


def test_reversals_count_hard_lateral_requests_that_change_side():
    # hard left, soft right (ignored), hard right (1), hard right, hard left (2); an undriven hard right is ignored
    assert reversals(_rows([0.9, -0.3, -0.8, -1.0, 0.6, -0.9], driven=[1, 1, 1, 1, 1, 0])) == 2
    assert reversals(_rows([0.4, -0.4, 0.45])) == 0


def test_side_swaps_count_the_nearest_member_changing_side():
    assert side_swaps(_rows([0] * 6, sides=["left", "", "right", "right", "left", "left"])) == 2


def test_trace_of_an_episode_through_the_model(tmp_path):
    """A `mixed` start through the MoveNet model: one row a step, the summary's shield rate the share of rows the
    policy drove whose shield rules are set, no perceived place while fewer than two people are held, the plot."""
    from test_contracts import run_in_process

    out = tmp_path / "trace"
    res = run_in_process(ROOT / "tools" / "trace_episode.py", ["--policy", "vector", "--scenario", "mixed",
                                                               "--perception", "movenet", "--seed", "500001",
                                                               "--out", str(out)])
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader(open(out / "trace.csv")))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == len(rows) and abs(summary["episode_time_s"] - 0.1 * len(rows)) < 1e-6
    driven = [r for r in rows if r["driven"] == "1"]
    assert driven and abs(summary["shield_intervention_rate"]
                          - sum(bool(r["shield_rules"]) for r in driven) / len(driven)) < 1e-9
    assert float(rows[0]["t_s"]) == 0.0
    few = [r for r in rows if int(r["members_seen"]) < 2]  # no group, hence no perceived place, with fewer than two
    assert few and all(r["seen_place_distance_m"] == "nan" for r in few)
    assert any(r["seen_place_distance_m"] != "nan" for r in rows)
    assert summary["failure"] in ("none", "wrong place", "short", "near", "violation")
    assert (out / "trace.png").stat().st_size > 10_000
    assert f"seed 500001: {summary['outcome']}" in res.stdout
