"""Ablations of the observation model: the oracle's parts of the observation, and the tool's table."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.analysis.ablation import ABLATIONS, pick, table
from ssbl_pb.analysis.compare import paired_success
from ssbl_pb.core import observation as ob
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.errors import UserError
from ssbl_pb.params import ConfigError

MEMBERS, GROUP = slice(ob.MEMBERS, ob.HEADING), slice(ob.SLOT_X, ob.OSPACE_RADIUS + 1)
PLACE = slice(ob.SLOT_X, ob.SLOT_Y + 1)


def _perceived_and_true(oracle: list[str]) -> list[tuple[np.ndarray, np.ndarray]]:
    env = ApproachGroupEnv("mixed", perception={"oracle": oracle})
    env.reset(seed=500003)
    sim, out = env.sim, []
    for _ in range(30):
        env.step(np.array([0.6, 0.0]))
        seen = sim.observations()[0]
        keep, sim.perceived = sim.perceived, None
        out.append((seen, sim.observations()[0]))
        sim.perceived = keep
    return out


def test_the_oracle_gives_the_parts_named_from_the_true_state_and_the_rest_as_perceived() -> None:
    both = _perceived_and_true(["members", "place", "centre"])
    assert all(np.array_equal(s[MEMBERS], t[MEMBERS]) and np.array_equal(s[GROUP], t[GROUP]) for s, t in both)
    members = _perceived_and_true(["members"])
    assert all(np.array_equal(s[MEMBERS], t[MEMBERS]) for s, t in members)
    assert any(not np.allclose(s[GROUP], t[GROUP], atol=1e-3) for s, t in members)  # the place as perceived
    place = _perceived_and_true(["place"])
    assert all(np.array_equal(s[PLACE], t[PLACE]) for s, t in place)
    assert any(not np.allclose(s[GROUP], t[GROUP], atol=1e-3) for s, t in place)  # the centre as perceived
    none = _perceived_and_true([])
    assert any(not np.allclose(s[MEMBERS], t[MEMBERS], atol=1e-3) for s, t in none)


def test_an_unknown_oracle_part_is_refused_by_name() -> None:
    with pytest.raises(ConfigError, match="oracle.*'walls'.*members"):
        ApproachGroupEnv("mixed", perception={"oracle": ["walls"]})


def test_ablations_are_picked_by_name_in_the_tools_order() -> None:
    assert [a.name for a in pick("true-members,model")] == ["model", "true-members"]
    assert pick(None) == list(ABLATIONS) and ABLATIONS[0].perception == {}  # the model itself first
    with pytest.raises(UserError, match=r"unknown ablation\(s\) \['bogus'\]"):
        pick("model,bogus")
    with pytest.raises(UserError, match="--only ','"):  # nothing named: no empty table
        pick(",")


def test_each_ablation_is_paired_with_the_first_seed_by_seed() -> None:
    """Seeds 1-10: the first row joins 1-6, the ablation 3-10: it gained 7-10 (4) and lost 1-2 (2). McNemar's
    exact p on 4 against 2 discordant pairs: 2 * P(X <= 2 | n=6, 1/2) = 2 * (1 + 6 + 15) / 64 = 0.6875; on 8
    against 0: 2 / 2**8."""
    first = {s: float(s <= 6) for s in range(1, 11)}
    v = paired_success({s: float(s >= 3) for s in range(1, 11)}, first, "model")
    assert (v["against"], v["gained"], v["lost"]) == ("model", 4, 2) and v["p"] == pytest.approx(0.6875)
    more = {s: float(s <= 8) for s in range(1, 21)}
    assert paired_success(more, {s: 0.0 for s in range(1, 21)}, "model")["p"] == pytest.approx(2 / 2 ** 8)


def test_the_table_gives_success_shield_and_failures_per_ablation() -> None:
    rows = [{"name": "model", "what": "as it is", "success_rate": 0.835, "shield_intervention_rate": 0.363,
             "failures": {"violation": 0, "wrong place": 9, "short": 17, "near": 7}, "versus": None},
            {"name": "true-place", "what": "the place", "success_rate": 0.92, "shield_intervention_rate": 0.303,
             "failures": {"violation": 1, "wrong place": 3, "short": 7, "near": 5},
             "versus": {"against": "model", "gained": 21, "lost": 4, "p": 0.00091}}]
    text = table(rows, {"policy": "vector", "scenario": "mixed", "detector": "movenet", "episodes": 200,
                        "seed": 500000})
    assert "| model | as it is | 83.5 % | 36.3 % | 0 | 9 | 17 | 7 | - |" in text
    assert "| true-place | the place | 92.0 % | 30.3 % | 1 | 3 | 7 | 5 | +21 / -4 (p 0.00091) |" in text
    assert ("| ablation | what it takes away | success | shield | violation | wrong place | short | near | "
            "joined / lost vs model (McNemar p) |") in text


def test_the_tool_writes_each_ablations_evaluation_and_the_table(tmp_path) -> None:
    spec = importlib.util.spec_from_file_location("ablate_tool", Path(__file__).parents[1] / "tools" /
                                                  "ablate_perception.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)  # type: ignore[union-attr]
    out = tmp_path / "abl"
    assert tool.main(["--policy", "straight", "--only", "model,true-all", "--episodes", "1", "--out",
                      str(out)]) == 0
    data = json.loads((out / "ablations.json").read_text())
    assert [r["name"] for r in data["rows"]] == ["model", "true-all"] and data["detector"] == "movenet"
    assert data["rows"][0]["versus"] is None and data["rows"][1]["versus"]["against"] == "model"
    assert (out / "model" / "episodes.csv").is_file() and (out / "true-all" / "summary.json").is_file()
    assert "| true-all |" in (out / "ablations.md").read_text()
