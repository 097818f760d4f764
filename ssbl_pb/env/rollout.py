"""Run seeded episodes of any policy and collect their metrics, in parallel when asked.

Episode ``i`` of a run with seed ``S`` is reset with seed ``S + i``, so the same seed gives the same episodes
whatever the number of workers (results are put back in episode order).
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import signal
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import gymnasium as gym
import numpy as np

from .metrics import episode_metrics
from .policies import Policy
from .reward import TERMS


@dataclasses.dataclass
class EpisodeResult:
    """Metrics (flat dict: metrics, ``return`` and each summed reward term) and the recorded trajectory."""

    seed: int
    metrics: dict[str, float]
    trajectory: list[dict[str, Any]]
    info: dict[str, Any]


def run_episode(env: gym.Env, policy: Policy, seed: int, keep_trajectory: bool = True,
                on_step: Callable[[gym.Env], None] | None = None) -> EpisodeResult:
    """One episode of ``policy`` in ``env`` (any obs mode; the core env must record its trajectory)."""
    core = env.unwrapped
    core.record = True
    obs, reset_info = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset()
    state, start = None, np.ones((1,), dtype=bool)
    if on_step is not None:
        on_step(env)
    while True:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.zeros((1,), dtype=bool)
        obs, _, terminated, truncated, info = env.step(action)
        if on_step is not None:
            on_step(env)
        if terminated or truncated:
            break
    m = episode_metrics(core.trajectory, info["success"], info["collision"], info["violation"], core.task,
                        core.dt, core.social.fov_half_angle_deg, core.social.human_radius + core.robot_params.radius)
    sums = info["episode_terms"]
    m["return"] = sums["reward"]
    for k in TERMS:
        m[f"term_{k}"] = sums[k]
    m["seed"] = float(seed)
    return EpisodeResult(seed, m, core.trajectory if keep_trajectory else [], {**reset_info, **info})


# -- parallel runs: each worker builds its own env and policy once ------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_worker(make: Callable[[], tuple[gym.Env, Policy]], child: bool = False) -> None:
    if child:  # Ctrl-C is the parent's to handle: workers are shut down, they print no tracebacks
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER["env"], _WORKER["policy"] = make()


def _run_seed(args: tuple[int, bool]) -> EpisodeResult:
    seed, keep = args
    policy = _WORKER["policy"]
    if hasattr(policy, "reseed"):
        policy.reseed(seed)
    return run_episode(_WORKER["env"], policy, seed, keep)


def run_episodes(make: Callable[[], tuple[gym.Env, Policy]], seeds: Iterable[int], workers: int = 1,
                 keep_trajectories: int = 0, progress: Callable[[int], None] | None = None) -> list[EpisodeResult]:
    """Episodes for ``seeds`` (in that order); ``make`` builds (env, policy) and must be picklable for
    ``workers > 1``. Trajectories are kept for the first ``keep_trajectories`` episodes only."""
    seeds = list(seeds)
    jobs = [(s, i < keep_trajectories) for i, s in enumerate(seeds)]
    if workers <= 1:
        _init_worker(make)
        out = []
        for job in jobs:
            out.append(_run_seed(job))
            if progress:
                progress(1)
        _WORKER["env"].close()
        return out
    # a worker that fails to start breaks the pool (an error), instead of being respawned for ever
    pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=_init_worker,
                               initargs=(make, True))
    out, done = [], False
    try:
        for res in pool.map(_run_seed, jobs, chunksize=max(1, len(jobs) // (8 * workers))):
            out.append(res)
            if progress:
                progress(1)
        done = True
    finally:
        pool.shutdown(wait=done, cancel_futures=True)
    return out
