"""The sweep's trial: train one configuration with one seed into its folder (a normal run directory), then
evaluate the trained policy on held-out episodes (``eval/`` inside it) and return the headline metrics."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..params import ConfigError, _check
from ..training.config import config_to_dict, load_config

# evaluation summary keys a trial returns (means over its episodes); the sweep's summary gives their mean and
# 95 % CI over seeds
METRICS = ("success_rate", "collision_rate", "violation_rate", "mean_return", "personal_zone_time_s",
           "human_displacement_m", "mean_jerk", "arrival_speed", "outside_fov_time_s", "time_to_success_s",
           "path_length_m")


@dataclasses.dataclass(frozen=True)
class EvalSpec:
    """How every trial of a sweep is evaluated: the same held-out episodes for all (paired across configs)."""

    episodes: int = 100  # per trial; 100 keeps one trial's success rate within about +-5 points at 90 %
    seed: int = 500_000  # the held-out seeds (docs/decisions.md, "Training"): no training run uses them
    scenario: str = ""  # "" = the scenario the configuration trains on
    model: str = "final"  # final (model.zip) or best (best/, picked on the in-training evaluation seeds)
    paths: int = 3  # episodes drawn in eval/paths.png (0: no plot)

    def __post_init__(self) -> None:
        for name, low in (("episodes", 1), ("seed", 0), ("paths", 0)):
            v = getattr(self, name)
            _check(isinstance(v, int) and not isinstance(v, bool) and v >= low, "eval", name, v,
                   f"an integer >= {low}")
        _check(isinstance(self.scenario, str), "eval", "scenario", self.scenario, "a scenario name")
        _check(self.model in ("final", "best"), "eval", "model", self.model, "'final' or 'best'")


@dataclasses.dataclass(frozen=True)
class TrainEvalTrial:
    """Train ``config`` (a full training config as ``config_to_dict`` gives it, seed included), then evaluate.

    ``group`` names the configuration the trial belongs to (the sweep's summary has one row per group)."""

    name: str
    group: str
    config: dict[str, Any]
    evaluation: EvalSpec

    def definition(self) -> dict[str, Any]:
        """What the result depends on; a stored result with another definition is stale."""
        return {"kind": "train_eval", "config": self.config, "eval": dataclasses.asdict(self.evaluation)}

    def __call__(self, trial_dir: Path) -> dict[str, Any]:
        # lazy: the worker's work, which keeps the sweep CLI from importing torch, SB3 and the tracker
        from ..analysis.evaluation import Setup, evaluate
        from ..training.run import train  # lazy: as above

        cfg = load_config(None, self.config)
        if not _trained(trial_dir, cfg):  # an unfinished run starts again from scratch: results stay exact
            train(cfg, trial_dir, overwrite=True)
        trained = json.loads((trial_dir / "summary.json").read_text())
        ev = self.evaluation
        env = dict(cfg.env)
        if cfg.obs_mode != "vector":
            env.update(camera_width=cfg.camera_size, camera_height=cfg.camera_size)
        # the default reward weights: returns are comparable across configurations that train with other weights
        setup = Setup(str(trial_dir if ev.model == "final" else trial_dir / "best"), cfg.obs_mode,
                      ev.scenario or cfg.scenario, tuple(sorted(env.items())))
        summary, _ = evaluate(setup, ev.episodes, ev.seed, trial_dir / "eval", workers=1, n_paths=ev.paths)
        out: dict[str, Any] = {m: finite(summary[m]) for m in METRICS}
        out.update(train_steps=int(trained["steps"]), train_wall_s=float(trained["wall_time_s"]))
        return out


def _trained(run_dir: Path, cfg: Any) -> bool:
    """The run directory holds a finished run of exactly this config."""
    if not ((run_dir / "summary.json").is_file() and (run_dir / "model.zip").is_file()):
        return False
    try:
        return load_config(run_dir / "config.yaml") == cfg
    except ConfigError:
        return False


def finite(value: Any) -> float | None:
    """A number as a float, NaN / inf / missing as None (valid JSON)."""
    if value is None:
        return None
    v = float(value)
    return v if math.isfinite(v) else None


def trial_name(config: str, seed: int) -> str:
    """``CONFIG,seed=S`` (``seed=S`` alone for a sweep's ``base`` configuration)."""
    return f"seed={seed}" if config == "base" else f"{config},seed={seed}"


def trials_for(configs: dict[str, Any], seeds: Sequence[int], evaluation: EvalSpec | None = None
               ) -> list[TrainEvalTrial]:
    """One trial per named training config (``TrainConfig``) and seed, named as a sweep names them: a list for
    ``dispatch.run_trials`` (e.g. Table I's rows x seeds)."""
    return [TrainEvalTrial(trial_name(name, seed), name, {**config_to_dict(cfg), "seed": seed},
                           evaluation or EvalSpec())
            for name, cfg in configs.items() for seed in seeds]
