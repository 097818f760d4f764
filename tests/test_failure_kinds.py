"""Why episodes through the observation model failed: the end state's columns and their classification."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from ssbl_pb.agents.metrics import FAILURE_KINDS, failure_counts, failure_kind
from ssbl_pb.analysis.evaluation import Setup, evaluate
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv


@pytest.mark.parametrize("success, violation, slot_error, place_distance, kind", [
    (True, False, 3.0, 3.0, ""),  # joined: no failure, whatever perception believed
    (False, True, 0.0, 0.0, "violation"),
    (False, False, 0.61, 0.0, "wrong place"),  # beyond 2 x 0.3 m
    (False, False, math.inf, 0.0, "wrong place"),  # too few people known for a group
    (False, False, 0.6, 0.61, "short"),  # the place about right (2 x 0.3 m is not off), the robot away from it
    (False, False, 0.6, 0.6, "near"),
    (False, False, 0.1, 0.35, "near"),
])
def test_a_failure_is_named_by_where_the_place_was_perceived_and_where_the_robot_ended(
        success: bool, violation: bool, slot_error: float, place_distance: float, kind: str) -> None:
    assert failure_kind(success, violation, slot_error, place_distance, tolerance=0.3) == kind


def test_failures_are_counted_by_kind() -> None:
    rows = [{"success": s, "violation": v, "perceived_slot_error_m": e, "perceived_place_distance_m": d}
            for s, v, e, d in [(1.0, 0.0, 9.0, 9.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 2.0, 0.1),
                               (0.0, 0.0, 0.2, 1.5), (0.0, 0.0, 0.2, 1.5), (0.0, 0.0, 0.1, 0.4)]]
    assert failure_counts(rows, 0.3) == {"violation": 1, "wrong place": 1, "short": 2, "near": 1}
    assert tuple(failure_counts([], 0.3)) == FAILURE_KINDS


def test_the_end_state_of_perception_is_measured_against_the_true_group() -> None:
    env = ApproachGroupEnv("mixed", perception=True)
    env.reset(seed=5)
    sim = env.sim
    for _ in range(40):
        env.step(np.zeros(2))
    cp, n = sim.perceived.copies[0], int(sim.groups_state.count[0])
    sim.perceived.known[0] = True
    sim.perceived.slot[0] = sim.slot[0] + np.array([0.3, 0.4])  # a place believed 0.5 m off
    sim.pose[0, :2] = sim.perceived.slot[0] + np.array([0.0, 1.2])  # the robot 1.2 m from it
    cp.tracker.members = {k: m for k, m in enumerate(
        [type("M", (), {"pos": xy.copy()})() for xy in sim.groups_state.pos[0, :n - 1]])}  # the last never found
    cp.members = list(cp.tracker.members.values())
    out = sim.perceived_outcome(0)
    assert out["slot_error_m"] == pytest.approx(0.5) and out["place_distance_m"] == pytest.approx(1.2)
    assert out["members_unfound"] == 1.0
    sim.perceived.known[0] = False  # fewer than two people known: no place at all
    assert sim.perceived_outcome(0)["slot_error_m"] == math.inf


def test_evaluate_reports_why_episodes_through_the_model_failed_and_nothing_of_it_without(tmp_path) -> None:
    on = Setup("random", scenario="mixed", env_kwargs=(("perception", True),))
    summary, results = evaluate(on, 4, 500000, tmp_path / "on", n_paths=0)
    failed = sum(1 for r in results if not r.metrics["success"])
    assert sum(summary["failures"].values()) == failed > 0  # random steps seldom join (played one by one: run_episode)
    assert json.loads((tmp_path / "on" / "summary.json").read_text())["failures"] == summary["failures"]
    with open(tmp_path / "on" / "episodes.csv") as f:
        row = next(csv.DictReader(f))
    assert {"perceived_slot_error_m", "perceived_place_distance_m", "members_unfound"} <= set(row)
    _, batch = evaluate(Setup("straight", scenario="mixed", env_kwargs=(("perception", True),)), 2, 500000,
                        tmp_path / "batch", n_paths=0)  # played at once (run_batch)
    assert all(r.metrics["members_unfound"] >= 0 for r in batch)
    summary, results = evaluate(Setup("straight", scenario="mixed"), 1, 500000, tmp_path / "off", n_paths=0)
    assert "failures" not in summary and "members_unfound" not in results[0].metrics
