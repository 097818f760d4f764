"""A training recipe: stages run one after another, each a training config that starts from the stage before
(fine-tuning, as rl-baselines3-zoo's hyperparameter files but with a curriculum), in one command, resumable as a
whole, with one learning curve across them.

A recipe YAML::

    name: vector
    stages:                                       # config paths are relative to the recipe file
      - {name: stage1, config: ../shipped/vector_stage1.yaml}                     # from scratch
      - {name: stage2, config: ../shipped/vector_stage2.yaml, init: best}        # the stage before's best model
      - {name: stage8, config: ../shipped/vector_stage8.yaml, init: final, set: {shield_at_place: false}}

``run_recipe`` trains stage i in ``OUT/NN_name`` (``train``), skips a stage whose run finished and resumes one a
signal or a crash left half done (``resume``), so the same command continues the whole recipe. ``--seed`` sets
every stage's seed. ``OUT/learning_curve.csv``, ``eval.csv`` and ``learning_curve.png`` join the stages' logs
with their steps counted from the recipe's start; ``OUT/recipe.json`` records the stages (each with the commit it
trained at), the seed and the commit of the final stage."""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..files import source_commit, write_json, write_text
from ..params import ConfigError, load_yaml
from .config import load_config
from .curves import plot_learning_curve
from .run import finished_at, resume, train

INITS = ("none", "final", "best")


@dataclasses.dataclass(frozen=True)
class Stage:
    """One stage: its name (the run folder's suffix), its training config, what it starts from (``none``: from
    scratch; ``final`` or ``best``: the stage before's final or best evaluated model) and config overrides."""

    name: str
    config: Path
    init: str = "final"
    overrides: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Recipe:
    name: str
    stages: tuple[Stage, ...]
    path: Path


def load_recipe(path: str | Path) -> Recipe:
    """Read and check a recipe YAML (errors name the file and the field); every stage's config is loaded once,
    with its overrides, so a bad stage fails before the first one trains."""
    path = Path(path)
    data = load_yaml(path)
    unknown = sorted(set(data) - {"name", "stages"})
    if unknown:
        raise ConfigError(f"{path}: unknown key {unknown[0]!r}; a recipe has name and stages")
    items = data.get("stages")
    if not isinstance(items, list) or not items:
        raise ConfigError(f"{path}: stages: expected a non-empty list of {{name, config, init, set}}")
    stages, names = [], set()
    for i, item in enumerate(items):
        where = f"{path}: stages[{i}]"
        if not isinstance(item, dict) or not {"name", "config"} <= set(item) or set(item) - {"name", "config",
                                                                                              "init", "set"}:
            raise ConfigError(f"{where}: expected a mapping with name and config (and optional init, set)")
        name = item["name"]
        if not isinstance(name, str) or not name.replace("_", "").replace("-", "").isalnum() or name in names:
            raise ConfigError(f"{where}.name {name!r}: expected a unique name of letters, digits, - and _")
        names.add(name)
        init = item.get("init", "none" if i == 0 else "final")
        if init not in INITS or (i == 0) != (init == "none"):
            expected = "none (the first stage trains from scratch)" if i == 0 else "final or best"
            raise ConfigError(f"{where}.init {init!r}: expected {expected}")
        over = item.get("set") or {}
        if not isinstance(over, dict):
            raise ConfigError(f"{where}.set: expected a mapping of config keys, e.g. {{shield_at_place: false}}")
        config = (path.parent / str(item["config"])).resolve()
        if not config.is_file():
            raise ConfigError(f"{where}.config: {config} does not exist")
        load_config(config, over)  # its own errors name the file and the key
        stages.append(Stage(name, config, init, over))
    return Recipe(str(data.get("name") or path.stem), tuple(stages), path)


def stage_dir(out: Path, i: int, stage: Stage) -> Path:
    return out / f"{i + 1:02d}_{stage.name}"


def run_recipe(recipe: Recipe, out: Path, seed: int | None = None,
               report: Callable[[str], None] = print) -> dict[str, Any]:
    """Train every stage not yet finished (resuming a half-done one), then join the logs; returns the record
    written to ``out/recipe.json``."""
    extra = {} if seed is None else {"seed": seed}
    out.mkdir(parents=True, exist_ok=True)
    before: Path | None = None
    for i, stage in enumerate(recipe.stages):
        folder = stage_dir(out, i, stage)
        label = f"stage {i + 1}/{len(recipe.stages)} {stage.name}"
        if finished_at(folder) is not None:
            report(f"{label}: finished, skipped ({folder})")
        elif (folder / "config.yaml").is_file():
            report(f"{label}: resuming {folder}")
            resume(folder)
        else:
            start = None if stage.init == "none" else (before / "best" if stage.init == "best" else before)
            report(f"{label}: training {folder}" + (f" from {start}" if start else " from scratch"))
            train(load_config(stage.config, {**stage.overrides, **extra}, env_check=True), folder, init_from=start)
        before = folder
    return join_stages(recipe, out, seed)


def join_stages(recipe: Recipe, out: Path, seed: int | None) -> dict[str, Any]:
    """``out``'s learning curve, evaluations and record across the finished stages (steps from the start)."""
    offset, bounds = 0, []
    logs: dict[str, list[dict[str, str]]] = {"learning_curve.csv": [], "eval.csv": []}
    for i, stage in enumerate(recipe.stages):
        folder = stage_dir(out, i, stage)
        for name, rows in logs.items():
            if (folder / name).is_file():
                with open(folder / name) as fh:
                    rows.extend({**r, "step": str(int(float(r["step"])) + offset)} for r in csv.DictReader(fh))
        steps = finished_at(folder) or 0
        done = json.loads((folder / "summary.json").read_text()) if (folder / "summary.json").is_file() else {}
        bounds.append({"stage": stage.name, "dir": str(folder), "config": str(stage.config), "init": stage.init,
                       "set": stage.overrides, "first_step": offset, "steps": steps, "commit": done.get("commit")})
        offset += steps
    for name, rows in logs.items():
        if rows:
            fields = list(rows[0])
            lines = [",".join(fields)] + [",".join(r.get(f, "") for f in fields) for r in rows]
            write_text(out / name, "\n".join(lines) + "\n")
    last = stage_dir(out, len(recipe.stages) - 1, recipe.stages[-1])
    baselines = json.loads((last / "baselines.json").read_text()) if (last / "baselines.json").is_file() else {}
    plot_learning_curve(out, baselines)
    # the commit the final model was trained at (each stage's in ``stages``; a stage trained before stages recorded
    # theirs: the checkout's now)
    commit = bounds[-1]["commit"] or source_commit()
    record = {"recipe": str(recipe.path), "name": recipe.name, "seed": seed, "commit": commit,
              "total_steps": offset, "stages": bounds, "final_model": str(last)}
    write_json(out / "recipe.json", record)
    return record



def provenance(run_dir: Path) -> dict[str, Any]:
    """Where a run came from, for a shipped policy's record: its config's seed, and, when it is a stage of a
    recipe (``run_recipe``'s folder holds its ``recipe.json``), the recipe, its seed and the commit it ran at."""
    run_dir = Path(run_dir)
    config = run_dir / "config.yaml"
    out: dict[str, Any] = {"seed": load_config(config).seed if config.is_file() else None, "recipe": None}
    record = run_dir.parent / "recipe.json"
    try:
        data = json.loads(record.read_text())
        stage = next(s["stage"] for s in data["stages"] if Path(s["dir"]).resolve() == run_dir.resolve())
    except (OSError, ValueError, KeyError, TypeError, StopIteration):
        return out
    return {**out, "recipe": data.get("recipe"), "recipe_seed": data.get("seed"), "stage": stage,
            "commit": data.get("commit")}
