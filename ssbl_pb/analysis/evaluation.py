"""Evaluate a policy (baseline, shipped or trained) over seeded episodes; used by tools/evaluate.py & co."""

from __future__ import annotations

import dataclasses
import os
import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym

from ..agents.metrics import failure_counts
from ..agents.policies import BASELINES, Policy, make_policy
from ..agents.rollout import EpisodeResult, run_episodes
from ..agents.trained import load_trained, policy_env_kwargs, shield_at_place
from ..core.shield import ShieldParams
from ..env.gymenv.approach import make_env
from ..errors import UserError
from ..files import check_output_path, make_stage_dir, output_dir
from ..perception.groups.observation_model import PerceptionParams
from ..policies import SHIPPED
from .report import plot_paths, summarize, write_csv, write_json


@dataclasses.dataclass(frozen=True)
class Setup:
    """Everything needed to build (env, policy) in a worker process (picklable)."""

    policy: str
    obs_mode: str = "vector"
    scenario: str = "default"
    env_kwargs: tuple[tuple[str, Any], ...] = ()
    shield: bool | None = None  # a trained policy's safety shield: None = as trained, else forced on/off

    def __call__(self) -> tuple[gym.Env, Policy]:
        # a policy on a frozen autoencoder brings its camera mode and encoder (env.gymenv.encoded)
        kwargs = {"obs_mode": self.obs_mode, **dict(self.env_kwargs), **policy_env_kwargs(self.policy)}
        env = make_env(scenario=self.scenario, **kwargs)
        return env, build_policy(self.policy, env, self.shield)


def build_policy(spec: str, env: gym.Env, shield: bool | None = None) -> Policy:
    """A baseline by name, the shipped model by name, or a trained model from a path (``shield``: see
    ``Setup``; baselines never use it)."""
    core = env.unwrapped
    if spec in BASELINES:
        if spec != "random" and env.observation_space != core.observation_space:
            raise UserError(f"policy '{spec}' reads the vector observation; use --obs-mode vector")
        return make_policy(spec, core.robot_params, core.social, seed=0)
    # the shield brakes within this env's (possibly calibrated) robot limits, as the model was trained
    return load_trained(spec, env.observation_space, shield, ShieldParams.of(core, shield_at_place(spec)))


def check_policy_spec(spec: str, flag: str = "--policy") -> None:
    """A baseline, a shipped policy or an existing model path; the error names ``flag``."""
    if spec in BASELINES or spec in SHIPPED:
        return
    if not (spec.endswith(".zip") or Path(spec).is_dir()) or not Path(spec).exists():
        raise UserError(f"{flag} {spec!r}: expected one of {list(BASELINES) + list(SHIPPED)}, a trained model "
                         f"(.zip) or a run directory that exists")


def evaluate(setup: Setup, episodes: int, seed: int, out: Path, workers: int = 1, n_paths: int = 6,
             progress: Any = None) -> tuple[dict[str, Any], list[EpisodeResult]]:
    """Run the episodes and write ``episodes.csv``, ``summary.json`` and ``paths.png`` into ``out``.

    Files are first written to a staging directory inside ``out`` and moved in place at the end, so an
    interrupted run leaves no partial output.
    """
    check_counts(episodes=(episodes, 1), paths=(n_paths, 0), workers=(workers, 1))
    check_policy_spec(setup.policy)
    check_output_path(out)
    env, _ = setup()  # fail fast on a bad model / obs mode / scenario before any episode or output
    room, tolerance = env.unwrapped.world_params.room_size, env.unwrapped.task.slot_tolerance
    env.close()
    results = run_episodes(setup, range(seed, seed + episodes), workers, keep_trajectories=n_paths,
                           progress=progress)
    rows = [r.metrics for r in results]
    # the observation model on (the policy saw the group as deploy's perception would) or off (the true state)
    perceived = PerceptionParams.of(dict(setup.env_kwargs).get("perception"))
    summary = summarize(rows, {"policy": setup.policy, "obs_mode": setup.obs_mode, "scenario": setup.scenario,
                               "perception": "off" if perceived is None else f"on ({perceived.detector})",
                               "seed": seed})
    if perceived is not None:  # why the episodes through the model failed (``metrics.failure_kind``)
        summary["failures"] = failure_counts(rows, tolerance)
    with output_dir(out) as out:
        stage = make_stage_dir(out, ".staging-")
        try:
            write_csv(stage / "episodes.csv", rows)
            write_json(stage / "summary.json", summary)
            shown = [r for r in results if r.trajectory][:n_paths]
            if shown:
                plot_paths(stage / "paths.png", [r.trajectory for r in shown], episode_titles(shown), room)
            for f in stage.iterdir():
                os.replace(f, out / f.name)
        finally:
            shutil.rmtree(stage, ignore_errors=True)
    return summary, results


def check_counts(**values: tuple[int, int]) -> None:
    """``name=(value, minimum)`` pairs of command-line counts; the error names the flag (``--name``)."""
    for name, (value, low) in values.items():
        if not isinstance(value, int) or value < low:
            raise UserError(f"--{name.replace('_', '-')} {value}: expected an integer >= {low}")


def episode_titles(results: list[EpisodeResult]) -> list[str]:
    """'seed S: success' or 'seed S: fail (why)' with the group, for path plots."""
    return [f"seed {r.seed}: {outcome(r.metrics)} ({r.info.get('formation', '')} {r.info.get('n_humans', '')})"
            for r in results]


def outcome(metrics: dict[str, Any]) -> str:
    """Why an episode ended, in words: success, or what failed."""
    if metrics.get("success"):
        return "success"
    for key, why in (("obstacle_collision", "collided with a wall or an obstacle"),
                     ("collision", "collided with a member"), ("violation", "entered a member's intimate zone")):
        if metrics.get(key):
            return f"fail: {why}"
    return "fail: time out before joining"
