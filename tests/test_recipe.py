"""A training recipe: stages in one command, each from the one before, resumable as a whole, one curve across."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
import yaml

from ssbl_pb.params import ConfigError
from ssbl_pb.training.recipe import load_recipe, run_recipe

ROOT = Path(__file__).resolve().parents[1]
TINY = {"n_envs": 2, "total_steps": 128, "eval_every": 64, "eval_episodes": 1, "baseline_episodes": 1,
        "checkpoint_every": 64, "ppo": {"n_steps": 32, "batch_size": 32, "n_epochs": 1, "net_arch": [8, 8]}}


def write_recipe(folder: Path, stages: list[dict]) -> Path:
    base = yaml.safe_load((ROOT / "configs" / "vector_ff.yaml").read_text())
    (folder / "tiny.yaml").write_text(yaml.safe_dump({**base, **TINY, "ppo": {**base.get("ppo", {}), **TINY["ppo"]}}))
    path = folder / "recipe.yaml"
    path.write_text(yaml.safe_dump({"name": "tiny", "stages": stages}))
    return path


def test_stages_run_in_order_each_from_the_one_before_and_a_rerun_continues(tmp_path: Path) -> None:
    recipe = load_recipe(write_recipe(tmp_path, [
        {"name": "first", "config": "tiny.yaml"},
        {"name": "second", "config": "tiny.yaml", "init": "best", "set": {"action_smoothing": 0.5}}]))
    out = tmp_path / "out"
    said: list[str] = []
    record = run_recipe(recipe, out, seed=5, report=said.append)
    first, second = out / "01_first", out / "02_second"
    assert [s["steps"] for s in record["stages"]] == [128, 128] and record["total_steps"] == 256
    assert "from scratch" in said[0] and f"from {first / 'best'}" in said[1]
    cfg2 = yaml.safe_load((second / "config.yaml").read_text())
    assert cfg2["seed"] == 5 and cfg2["action_smoothing"] == 0.5
    with open(out / "eval.csv") as fh:  # one curve: the second stage's evaluations counted from the first's end
        steps = [int(r["step"]) for r in csv.DictReader(fh)]
    assert steps == sorted(steps) and steps[-1] > 128 >= steps[0]
    assert (out / "learning_curve.png").is_file() and json.loads((out / "recipe.json").read_text())["seed"] == 5
    from ssbl_pb.training.run import process_commit

    # each stage records the commit of the code that trained it (this process's), the recipe the final stage's
    assert [s["commit"] for s in record["stages"]] == [process_commit()] * 2 and record["commit"] == process_commit()
    from ssbl_pb.agents.trained import resolve_model

    ckpt = sorted((second / "checkpoints").glob("ckpt_*.zip"))[-1]  # a checkpoint: its own statistics, the run's config
    model, norm, config = resolve_model(str(ckpt))
    assert norm == ckpt.with_name(f"{ckpt.stem}_vecnormalize.pkl") and config["action_smoothing"] == 0.5
    # stopped during the second stage: the same call skips the first and trains the second again
    mtime = (first / "model.zip").stat().st_mtime_ns
    shutil.rmtree(second)
    said.clear()
    run_recipe(recipe, out, seed=5, report=said.append)
    assert said[0].startswith("stage 1/2 first: finished, skipped") and "training" in said[1]
    assert (first / "model.zip").stat().st_mtime_ns == mtime and (second / "summary.json").is_file()


@pytest.mark.parametrize("stages, message", [
    ([], "stages: expected a non-empty list"),
    ([{"name": "a", "config": "tiny.yaml", "init": "best"}], "stages[0].init 'best': expected none"),
    ([{"name": "a", "config": "tiny.yaml"}, {"name": "a", "config": "tiny.yaml"}], "stages[1].name 'a'"),
    ([{"name": "a", "config": "missing.yaml"}], "stages[0].config: "),
    ([{"name": "a", "config": "tiny.yaml", "set": {"total_steps": -1}}], "total_steps"),
    ([{"name": "a", "config": "tiny.yaml", "epochs": 3}], "stages[0]: expected a mapping with name and config"),
])
def test_a_bad_recipe_names_the_file_and_the_field(tmp_path: Path, stages: list, message: str) -> None:
    path = write_recipe(tmp_path, stages)
    with pytest.raises(ConfigError, match=None) as err:
        load_recipe(path)
    assert message in str(err.value)


def test_the_shipped_recipe_is_the_shipped_chain() -> None:
    recipe = load_recipe(ROOT / "configs" / "recipes" / "vector.yaml")
    assert [s.config.name for s in recipe.stages] == [f"vector_stage{i}.yaml" for i in range(1, 10)] + ["vector.yaml"]
    assert [s.init for s in recipe.stages][:2] == ["none", "best"]
    assert recipe.stages[7].overrides == {"shield_at_place": False}


def test_the_command_line_refuses_flags_a_recipe_sets_itself(tmp_path: Path, capsys) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("train_pb", ROOT / "tools" / "train_pb.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    path = write_recipe(tmp_path, [{"name": "a", "config": "tiny.yaml"}])
    assert tool.main(["--recipe", str(path), "--total-steps", "10", "--set", "seed=1"]) != 0
    assert "drop --set, --total-steps (only --out and --seed apply)" in capsys.readouterr().err
    assert not (ROOT / "runs" / "tiny_recipe").exists()


def test_a_stage_knows_its_recipe_seed_and_commit(tmp_path: Path) -> None:
    from ssbl_pb.training.recipe import provenance

    stage = tmp_path / "out" / "01_first"
    stage.mkdir(parents=True)
    (stage / "config.yaml").write_text(yaml.safe_dump({**yaml.safe_load((ROOT / "configs" / "vector_ff.yaml")
                                                                       .read_text()), "seed": 9}))
    assert provenance(stage) == {"seed": 9, "recipe": None}  # a plain run
    (stage.parent / "recipe.json").write_text(json.dumps({"recipe": "r.yaml", "seed": 9, "commit": "abc1234",
                                                          "stages": [{"stage": "first", "dir": str(stage)}]}))
    assert provenance(stage) == {"seed": 9, "recipe": "r.yaml", "recipe_seed": 9, "stage": "first",
                                 "commit": "abc1234"}
