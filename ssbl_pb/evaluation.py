"""Evaluate a policy (baseline, shipped or trained) over seeded episodes; used by tools/evaluate.py & co."""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import gymnasium as gym

from .env.approach import make_env
from .env.policies import BASELINES, Policy, make_policy
from .env.rollout import EpisodeResult, run_episodes
from .errors import UserError
from .policies import SHIPPED
from .report import plot_paths, summarize, write_csv, write_json


class UsageError(UserError):
    """Bad command-line input; tools print the message and exit with code 2."""


@dataclasses.dataclass(frozen=True)
class Setup:
    """Everything needed to build (env, policy) in a worker process (picklable)."""

    policy: str
    obs_mode: str = "vector"
    scenario: str = "default"
    env_kwargs: tuple[tuple[str, Any], ...] = ()
    shield: bool | None = None  # a trained policy's safety shield: None = as trained, else forced on/off

    def __call__(self) -> tuple[gym.Env, Policy]:
        from .env.trained import policy_env_kwargs

        # a policy on a frozen autoencoder brings its camera mode and encoder (env.encoded)
        kwargs = {"obs_mode": self.obs_mode, **dict(self.env_kwargs), **policy_env_kwargs(self.policy)}
        env = make_env(scenario=self.scenario, **kwargs)
        return env, build_policy(self.policy, env, self.shield)


def build_policy(spec: str, env: gym.Env, shield: bool | None = None) -> Policy:
    """A baseline by name, the shipped model by name, or a trained model from a path (``shield``: see
    ``Setup``; baselines never use it)."""
    core = env.unwrapped
    if spec in BASELINES:
        if spec != "random" and env.observation_space != core.observation_space:
            raise UsageError(f"policy '{spec}' reads the vector observation; use --obs-mode vector")
        return make_policy(spec, core.robot_params, core.social, seed=0)
    from .env.shield import ShieldParams
    from .env.trained import load_trained

    # the shield brakes within this env's (possibly calibrated) robot limits
    return load_trained(spec, env.observation_space, shield, ShieldParams.from_env(core.robot_params, core.social,
                                                                                   core.task))


def check_policy_spec(spec: str) -> None:
    if spec in BASELINES or spec in SHIPPED:
        return
    if not (spec.endswith(".zip") or Path(spec).is_dir()) or not Path(spec).exists():
        raise UsageError(f"--policy {spec!r}: expected one of {list(BASELINES) + list(SHIPPED)}, a trained model "
                         f"(.zip) or a run directory that exists")


def prepare_out(out: Path) -> None:
    """Create ``out`` and make sure it is writable (before any episode runs)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UsageError(f"--out {out}: not a writable directory ({exc.strerror or exc})") from exc


def evaluate(setup: Setup, episodes: int, seed: int, out: Path, workers: int = 1, n_paths: int = 6,
             progress: Any = None) -> tuple[dict[str, Any], list[EpisodeResult]]:
    """Run the episodes and write ``episodes.csv``, ``summary.json`` and ``paths.png`` into ``out``.

    Files are first written to a staging directory inside ``out`` and moved in place at the end, so an
    interrupted run leaves no partial output.
    """
    if not isinstance(episodes, int) or episodes < 1:
        raise UsageError(f"--episodes {episodes}: expected an integer >= 1")
    check_policy_spec(setup.policy)
    prepare_out(out)
    env, _ = setup()  # fail fast on a bad model / obs mode before spawning workers
    room = env.unwrapped.world_params.room_size
    env.close()
    results = run_episodes(setup, range(seed, seed + episodes), workers, keep_trajectories=n_paths,
                           progress=progress)
    rows = [r.metrics for r in results]
    summary = summarize(rows, {"policy": setup.policy, "obs_mode": setup.obs_mode, "scenario": setup.scenario,
                               "seed": seed})
    stage = Path(tempfile.mkdtemp(dir=out, prefix=".staging-"))
    try:
        write_csv(stage / "episodes.csv", rows)
        write_json(stage / "summary.json", summary)
        shown = [r for r in results if r.trajectory][:n_paths]
        titles = [f"seed {r.seed}: {'success' if r.metrics['success'] else 'fail'} "
                  f"({r.info.get('formation', '')} {r.info.get('n_humans', '')})" for r in shown]
        plot_paths(stage / "paths.png", [r.trajectory for r in shown], titles, room)
        for f in stage.iterdir():
            os.replace(f, out / f.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return summary, results
