"""Sweep specifications: a YAML file with a base training config, a grid of overrides, seeds, fixed overrides and
how each trial is evaluated. The whole spec (every configuration of the grid) is validated before anything runs;
errors name the SPEC file and key.

    base: ../vector_ff.yaml          # relative to this file (or to the current directory)
    grid:                            # train_pb.py --set keys -> lists; the product is the set of configurations
      reward.w_smooth: [0.05, 0.3]
      ppo.learning_rate: [3.0e-4, 1.0e-4]
    seeds: [0, 1, 2, 3, 4]           # every configuration is trained once per seed
    set: {total_steps: 100000}       # fixed overrides (optional)
    eval: {episodes: 100, seed: 500000, scenario: mixed, model: final, paths: 3}   # optional
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import re
from pathlib import Path
from typing import Any

from ..core.reward import RewardWeights
from ..env.gymenv.approach import make_env
from ..errors import UserError
from ..params import ConfigError, from_dict, load_yaml
from ..training.config import PPOConfig, TrainConfig, config_to_dict, env_kwargs, load_config, nest_overrides
from .trial import EvalSpec, TrainEvalTrial, trial_name

SPEC_KEYS = ("base", "grid", "seeds", "set", "eval")
MAX_NAME = 100  # characters of a trial folder's name before it is shortened with a hash


class SpecError(ConfigError):
    """A sweep spec is invalid; the message names the SPEC file and key."""


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A validated spec: ``configs`` maps each configuration's name to its grid values, in grid order."""

    path: Path
    base: Path
    grid: dict[str, list[Any]]
    seeds: tuple[int, ...]
    fixed: dict[str, Any]
    evaluation: EvalSpec
    configs: dict[str, dict[str, Any]]
    resolved: dict[str, dict[str, Any]]  # configuration name -> the full training config (config_to_dict)

    def trials(self) -> list[TrainEvalTrial]:
        """One trial per configuration and seed (configurations in grid order, seeds in spec order)."""
        return [TrainEvalTrial(trial_name(cfg_name, seed), cfg_name, {**self.resolved[cfg_name], "seed": seed},
                               self.evaluation)
                for cfg_name in self.configs for seed in self.seeds]

    def describe(self) -> dict[str, Any]:
        """The spec as JSON (written to ``DIR/sweep.json``)."""
        return {"spec": str(self.path), "base": str(self.base), "grid": self.grid, "seeds": list(self.seeds),
                "set": self.fixed, "eval": dataclasses.asdict(self.evaluation), "configs": self.configs}


def load_spec(path: str | Path) -> SweepSpec:
    """Read and validate a sweep spec: keys, base config, every grid value and every configuration."""
    path = Path(path)
    data = load_yaml(path)
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise SpecError(f"{path}: unknown key(s) {unknown}; allowed: {list(SPEC_KEYS)}")
    base = _base(path, data.get("base"))
    seeds = _seeds(path, data.get("seeds"))
    fixed = _mapping(path, "set", data.get("set"))
    grid = _mapping(path, "grid", data.get("grid"))
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise SpecError(f"{path}: grid.{key} = {values!r}: expected a non-empty list of values")
        texts = [json.dumps(v, sort_keys=True) for v in values]
        if len(set(texts)) < len(texts):
            raise SpecError(f"{path}: grid.{key} = {values!r}: a value is listed twice")
    _check_keys(path, [("set", k) for k in fixed] + [("grid", k) for k in grid])
    evaluation = _evaluation(path, data.get("eval"))

    def config(pairs: dict[str, Any], where: str) -> Any:
        try:
            return load_config(base, nest_overrides(pairs))
        except ConfigError as exc:
            raise SpecError(f"{path}: {where}: {exc}") from exc

    config(fixed, "set")
    for key, values in grid.items():  # each value alone first, so that the error names it
        for v in values:
            config({**fixed, key: v}, f"grid.{key} = {v!r}")
    short = _short_keys(list(grid))
    configs: dict[str, dict[str, Any]] = {}
    resolved: dict[str, dict[str, Any]] = {}
    for combo in itertools.product(*grid.values()):
        values = dict(zip(grid, combo, strict=True))
        name = config_name(values, short)
        if name in configs:
            raise SpecError(f"{path}: grid: configurations {configs[name]} and {values} get the same name {name!r}")
        cfg = config({**fixed, **values}, f"configuration {name}")
        _check_env(path, name, cfg, evaluation)
        configs[name], resolved[name] = values, config_to_dict(cfg)
    return SweepSpec(path, base, grid, seeds, fixed, evaluation, configs, resolved)


def _base(path: Path, base: Any) -> Path:
    if not isinstance(base, str) or not base:
        raise SpecError(f"{path}: base = {base!r}: expected the path of a training config, e.g. "
                        "configs/vector_ff.yaml")
    for where in (path.parent / base, Path(base)):
        if where.is_file():
            return where.resolve()
    raise SpecError(f"{path}: base {base!r}: file not found (looked beside the spec, {path.parent / base}, and in "
                    f"the current directory)")


def _seeds(path: Path, seeds: Any) -> tuple[int, ...]:
    example = "a list of distinct integers, e.g. seeds: [0, 1, 2, 3, 4]"
    if seeds is None:
        raise SpecError(f"{path}: seeds: missing; expected {example}")
    ok = isinstance(seeds, list) and seeds and all(isinstance(s, int) and not isinstance(s, bool) for s in seeds)
    if not ok or len(set(seeds)) < len(seeds):
        raise SpecError(f"{path}: seeds = {seeds!r}: expected {example}")
    return tuple(seeds)


def _mapping(path: Path, key: str, value: Any) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(k, str) and k for k in value):
        raise SpecError(f"{path}: {key} = {value!r}: expected a mapping of train_pb.py --set keys (e.g. "
                        f"reward.w_smooth) to {'lists of values' if key == 'grid' else 'values'}")
    return dict(value)


def _check_keys(path: Path, keys: list[tuple[str, str]]) -> None:
    """Keys the config has (top level and the ppo / reward fields; env keys are checked by the config itself),
    no seed (the spec's seeds give it), none twice and none inside another."""
    top = {f.name for f in dataclasses.fields(TrainConfig)}
    nested = {"ppo": {f.name for f in dataclasses.fields(PPOConfig)},
              "reward": {f.name for f in dataclasses.fields(RewardWeights)}}
    for section, key in keys:
        parts = key.split(".")
        where = f"{path}: {section} key {key!r}"
        if parts[0] not in top:
            raise SpecError(f"{where}: the training config has no key {parts[0]!r}; keys: {sorted(top)}")
        if parts[0] == "seed":
            raise SpecError(f"{where}: the spec's seeds list sets the seed of each trial")
        if parts[0] in nested and (len(parts) != 2 or parts[1] not in nested[parts[0]]):
            raise SpecError(f"{where}: expected {parts[0]}.NAME with NAME in {sorted(nested[parts[0]])}")
    names = [k for _, k in keys]
    for a, b in itertools.permutations(names, 2):
        if a == b or b.startswith(a + "."):
            raise SpecError(f"{path}: key {b!r} is set twice (also as {a!r}) in set/grid")


def _evaluation(path: Path, data: Any) -> EvalSpec:
    if data is not None and not isinstance(data, dict):
        raise SpecError(f"{path}: eval = {data!r}: expected a mapping (episodes, seed, scenario, model, paths)")
    try:
        return from_dict(EvalSpec, data, "eval")
    except (ConfigError, TypeError) as exc:
        raise SpecError(f"{path}: {exc}") from exc


def _check_env(path: Path, name: str, cfg: Any, evaluation: EvalSpec) -> None:
    """The env of a configuration and its evaluation can be built (scenario, room, robot, social values), and a
    ``model: best`` evaluation has an in-training evaluation to pick from."""
    try:
        make_env(**env_kwargs(cfg)).close()
        if evaluation.scenario:
            make_env(**{**env_kwargs(cfg), "scenario": evaluation.scenario}).close()
    except UserError as exc:  # scenario names, room/robot/social values, calibration files
        raise SpecError(f"{path}: configuration {name}: {exc}") from exc
    if evaluation.model == "best" and cfg.eval_every > cfg.total_steps:
        raise SpecError(f"{path}: eval.model = 'best': configuration {name} evaluates only every {cfg.eval_every} of "
                        f"{cfg.total_steps} steps, so it has no best model; use model: final or a smaller eval_every")


def _short_keys(keys: list[str]) -> dict[str, str]:
    """Each grid key by its last part (``reward.w_smooth`` -> ``w_smooth``) unless two keys share it."""
    last = [k.rsplit(".", 1)[-1] for k in keys]
    return {k: (s if last.count(s) == 1 else k) for k, s in zip(keys, last, strict=True)}


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list | tuple):
        return "-".join(_text(v) for v in value)
    if isinstance(value, dict):
        return "-".join(f"{k}-{_text(v)}" for k, v in value.items())
    return str(value)


def config_name(values: dict[str, Any], short: dict[str, str] | None = None) -> str:
    """A configuration's folder-safe name from its grid values: ``w_smooth=0.05,learning_rate=0.0003`` (``base``
    for an empty grid); long names keep their first characters and end in a hash of the values."""
    if not values:
        return "base"
    short = short or {k: k for k in values}
    name = ",".join(f"{short[k]}={_text(v)}" for k, v in values.items())
    name = re.sub(r"[^A-Za-z0-9._=,+-]", "-", name)
    if len(name) > MAX_NAME:
        digest = hashlib.sha1(json.dumps(values, sort_keys=True, default=str).encode()).hexdigest()[:8]
        name = f"{name[:MAX_NAME - 9]}-{digest}"
    return name


__all__ = ["SpecError", "SweepSpec", "load_spec", "config_name", "trial_name"]
