"""Run seeded episodes of any policy and collect their metrics, in parallel when asked.

Episode ``i`` of a run with seed ``S`` is reset with seed ``S + i``, so the same seed gives the same episodes
whatever the number of workers (results are put back in episode order).
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing as mp
import os
import signal
import sys
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import gymnasium as gym
import numpy as np

from ..cli import children_ignore_sigint, die_with_parent
from ..core.layouts import body_radii
from ..core.reward import TERMS
from ..core.shield import RULES
from .metrics import episode_metrics
from .policies import Policy


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
    steps = 0
    shielded = np.zeros(len(RULES) + 1)  # steps changed by any rule, then by each of ``RULES``
    sim = getattr(core, "sim", None)
    while True:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.zeros((1,), dtype=bool)
        rules = shield_rules(policy, 1)[0]
        obs, _, terminated, truncated, info = env.step(action)
        driven = sim is None or bool(sim.driven[0])  # the policy's action, not one perception's search replaced
        steps += driven
        shielded += driven * rule_flags(rules)
        if on_step is not None:
            on_step(env)
        if terminated or truncated:
            break
    return _result(core, seed, core.trajectory, {**reset_info, **info}, keep_trajectory, _rates(shielded, steps))


def _rates(shielded: np.ndarray, steps: float) -> np.ndarray:
    """Shares of the steps the policy drove that its shield changed, by any rule then by each (NaN: it drove
    none)."""
    return shielded / steps if steps else np.full(len(shielded), math.nan)


def rule_flags(rules: np.ndarray | int) -> np.ndarray:
    """Per shield record (``RULE_*`` flags, shape (n,) or scalar), whether any rule acted, then each of ``RULES``
    (float (..., 1 + len(RULES)))."""
    r = np.asarray(rules, dtype=np.int64)[..., None]
    return np.concatenate([r != 0, (r & (1 << np.arange(len(RULES)))) != 0], axis=-1).astype(float)


def shield_rules(policy: Policy, n: int) -> np.ndarray:
    """Per row of the policy's last action (``n`` rows), the rules of its safety shield that changed it (``RULE_*``
    flags; all 0 for a policy without one); ``core.shield.SafetyShield.last``."""
    last = getattr(getattr(policy, "shield", None), "last", None)
    return np.zeros(n, dtype=np.int64) if last is None else np.asarray(last.rules, dtype=np.int64).reshape(n)


def _result(core: Any, seed: int, trajectory: list[dict[str, Any]], info: dict[str, Any],
            keep_trajectory: bool, shield_rates: np.ndarray) -> EpisodeResult:
    m = episode_metrics(trajectory, info["success"], info["collision"], info["violation"], core.task, core.dt,
                        core.social.fov_half_angle_deg, body_radii(core.social, core.robot_params.radius),
                        info.get("obstacle_collision", False))
    sums = info["episode_terms"]
    m["shield_intervention_rate"] = float(shield_rates[0])  # share of the steps the policy drove its shield changed
    for name, rate in zip(RULES, shield_rates[1:], strict=True):  # ... and each rule
        m[f"shield_{name}_rate"] = float(rate)
    if "perceived" in info:  # the observation model's end state (``BatchedApproach.perceived_outcome``)
        seen = info["perceived"]
        m.update(perceived_slot_error_m=seen["slot_error_m"], perceived_place_distance_m=seen["place_distance_m"],
                 members_unfound=seen["members_unfound"])
    m["return"] = sums["reward"]
    for k in TERMS:
        m[f"term_{k}"] = sums[k]
    m["seed"] = float(seed)
    return EpisodeResult(seed, m, trajectory if keep_trajectory else [], info)


def batchable(env: gym.Env, policy: Policy) -> bool:
    """Whether ``run_batch`` can play this pair: the Vector env itself (no wrappers) and a policy whose actions
    do not depend on per-episode reseeding (the random baseline)."""
    return env is env.unwrapped and hasattr(env, "sim") and not hasattr(policy, "reseed")


def run_batch(env: gym.Env, policy: Policy, seeds: list[int], keep: list[bool]) -> list[EpisodeResult]:
    """The episodes of ``seeds`` played at once in a batch of ``env``'s engine, one policy call per step for all
    of them: episode ``i`` is the one ``run_episode(env, policy, seeds[i])`` plays (same start, same steps)."""
    core = env.unwrapped
    sim = core.sim.like(len(seeds))
    infos = []
    for i, seed in enumerate(seeds):
        sim.seed(i, seed)
        infos.append(sim.reset(i))
    trajectories = [[{**sim.snapshot(i, 0.0), **sim.room_info(i), "keep_out": sim.keep_out(i, 0.0)}]
                    for i in range(len(seeds))]
    if hasattr(policy, "reset"):
        policy.reset()
    obs, state = sim.observations(), None
    start, active = np.ones(len(seeds), dtype=bool), np.ones(len(seeds), dtype=bool)
    out: list[EpisodeResult | None] = [None] * len(seeds)
    t = 0.0
    steps, shielded = np.zeros(len(seeds)), np.zeros((len(seeds), len(RULES) + 1))
    while active.any():
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start[:] = False
        rules = shield_rules(policy, len(seeds))
        _, terminated, truncated = sim.step(action)
        driven = active & sim.driven  # the policy's actions, not those perception's search or looks replaced
        steps += driven
        shielded += driven[:, None] * rule_flags(rules)
        t += core.dt
        obs = sim.observations()
        for i in np.flatnonzero(active).tolist():
            trajectories[i].append(sim.snapshot(i, t))
            if terminated[i] or truncated[i]:
                active[i] = False
                out[i] = _result(core, seeds[i], trajectories[i], {**infos[i], **sim.outcome(i)}, keep[i],
                                 _rates(shielded[i], steps[i]))
    return out  # type: ignore[return-value]


# -- parallel runs: each worker builds its own env and policy once ------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_worker(make: Callable[[], tuple[gym.Env, Policy]], parent: int | None = None) -> None:
    """Build a worker's env and policy; a pool worker (``parent``: the pool owner's pid) ignores Ctrl-C (the
    parent's to handle: it shuts the pool down, the workers print no tracebacks) and dies with its parent, even
    a SIGKILLed one (``cli.die_with_parent``: no worker of ~600 MB left running)."""
    if parent is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        die_with_parent(parent)
    _WORKER["env"], _WORKER["policy"] = make()
    if "torch" in sys.modules:  # small networks: threads only wait on each other (20x slower on a busy machine)
        sys.modules["torch"].set_num_threads(1)


def _run_jobs(jobs: list[tuple[int, bool]]) -> list[EpisodeResult]:
    env, policy = _WORKER["env"], _WORKER["policy"]
    if batchable(env, policy):
        return run_batch(env, policy, [s for s, _ in jobs], [k for _, k in jobs])
    out = []
    for seed, keep in jobs:
        if hasattr(policy, "reseed"):
            policy.reseed(seed)
        out.append(run_episode(env, policy, seed, keep))
    return out


def run_episodes(make: Callable[[], tuple[gym.Env, Policy]], seeds: Iterable[int], workers: int = 1,
                 keep_trajectories: int = 0, progress: Callable[[int], None] | None = None,
                 chunk: int = 50) -> list[EpisodeResult]:
    """Episodes for ``seeds`` (in that order); ``make`` builds (env, policy) and must be picklable for
    ``workers > 1``. Trajectories are kept for the first ``keep_trajectories`` episodes only. Episodes go in
    chunks of up to ``chunk``, each played at once where ``batchable`` (else one by one). The chunks depend on
    the seeds alone, not on ``workers``: a network's batched forward pass rounds differently in batches of other
    sizes, so results are the same to the bit with any number of workers."""
    seeds = list(seeds)
    jobs = [(s, i < keep_trajectories) for i, s in enumerate(seeds)]
    # enough chunks for 16 workers (the most cores we run on), none under 8 episodes (a batch still pays off)
    size = max(1, min(chunk, max(8, -(-len(jobs) // 16))))
    chunks = [jobs[k:k + size] for k in range(0, len(jobs), size)]
    out: list[EpisodeResult] = []
    if workers <= 1:
        _init_worker(make)
        try:
            for c in chunks:
                out += _run_jobs(c)
                if progress:
                    progress(len(c))
        finally:
            _WORKER["env"].close()
        return out
    # a worker that fails to start breaks the pool (an error), instead of being respawned for ever
    pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=_init_worker,
                               initargs=(make, os.getpid()))
    done = False
    try:
        with children_ignore_sigint():  # the workers start here: a Ctrl-C while they import is the parent's
            results = pool.map(_run_jobs, chunks)
        for res in results:
            out += res
            if progress:
                progress(len(res))
        done = True
    finally:
        pool.shutdown(wait=done, cancel_futures=True)
    return out
