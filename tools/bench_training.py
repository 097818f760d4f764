#!/usr/bin/env python
"""Training throughput: PPO on the Vector env vs on a trivial env with the same observation and action sizes,
both measured in one run, in two settings:

* ``sb3``: SB3's own defaults (``PPO("MlpPolicy", env)``: one env, 64x64 net, 2048 steps per update, 10 epochs);
  the trivial env in SB3's ``DummyVecEnv``, the Vector env as training runs it (``BatchedVecEnv`` of one copy)
  and, for reference, as a plain Gymnasium env in ``DummyVecEnv`` (``vector_env_dummy``);
* ``config``: our training config (configs/vector_ff.yaml: 8 envs, 2x128 net, VecNormalize, the agent's action
  smoothing, the safety shield and episode monitoring). The Vector env runs as training runs it, batched
  (``training.vec_env.BatchedVecEnv``: all 8 copies in one compiled step); the trivial env runs in SB3's own
  ``DummyVecEnv`` with ``Monitor`` and the smoothing wrapper (all but the shield, which is part of our agent's
  cost). ``vector_env_dummy`` is our env in ``DummyVecEnv`` too (one env object per copy), for reference.

The trivial env returns a stored observation (no sampling), so its figure is SB3's own cost per step.
Writes results/bench_training.json.
    python tools/bench_training.py
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, UserError, int_at_least, run

ROOT = Path(__file__).resolve().parents[1]

SETTINGS = ("sb3", "config")


def _trivial_env_class():  # noqa: ANN202 - built lazily so --help stays fast
    import gymnasium as gym
    import numpy as np

    from ssbl_pb.core.observation import OBS_SIZE

    class Trivial(gym.Env):
        """Episodes of 150 steps, a fixed observation, zero reward."""

        observation_space = gym.spaces.Box(-10, 10, (OBS_SIZE,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

        def __init__(self, **_: object) -> None:
            self.t = 0
            self.obs = np.random.default_rng(0).uniform(-1, 1, OBS_SIZE).astype(np.float32)

        def reset(self, *, seed=None, options=None):  # noqa: ANN001, ANN202
            super().reset(seed=seed)
            self.t = 0
            return self.obs.copy(), {}

        def step(self, action):  # noqa: ANN001, ANN202
            self.t += 1
            done = self.t >= 150
            return self.obs.copy(), 0.0, False, done, {"is_success": False} if done else {}

    return Trivial


def measure(setting: str, steps: int, overrides: dict | None = None, repeats: int = 3) -> dict[str, float]:
    """Env steps per second of PPO learning on the trivial env and on the Vector env (same setting); each env
    measured ``repeats`` times, interleaved, and the median kept (runs on this machine vary by ~15 %)."""
    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    import ssbl_pb.training.run as run
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.training.config import load_config
    from ssbl_pb.training.vec_env import BatchedVecEnv

    cfg = load_config(ROOT / "configs" / "vector_ff.yaml", overrides)
    torch.set_num_threads(cfg.torch_threads)
    trivial = _trivial_env_class()
    runs: dict[str, list[float]] = {}
    for name in ("trivial", "vector_env", "vector_env_dummy") * repeats:
        if setting == "sb3":  # the Vector env as training runs it (batched, one copy), and as a plain gym env
            venv = BatchedVecEnv(1) if name == "vector_env" else DummyVecEnv([trivial if name == "trivial" else
                                                                             make_env])
            model = PPO("MlpPolicy", venv, device="cpu", seed=0)
        else:
            real_make_env, env_cfg = run.make_env, cfg  # vector_env: as training builds it (batched)
            if name == "trivial":  # SB3's DummyVecEnv with the same wrappers around the trivial env (the shield
                run.make_env = lambda **kw: trivial()  # is part of our agent's cost, so not here)
                env_cfg = dataclasses.replace(cfg, safety_shield=False, vec_env="dummy")
            elif name == "vector_env_dummy":  # our env in SB3's DummyVecEnv, one env object per copy
                env_cfg = dataclasses.replace(cfg, vec_env="dummy")
            try:
                venv = run.make_vec_env(env_cfg, 0)
            finally:
                run.make_env = real_make_env
            model = run.build_model(cfg, venv, Path("/tmp/ssbl_bench_tb"))
            model.tensorboard_log = None
        t0 = time.perf_counter()
        model.learn(steps)
        runs.setdefault(f"{name}_steps_per_s", []).append(model.num_timesteps / (time.perf_counter() - t0))
        venv.close()
    out = {k: float(np.median(v)) for k, v in runs.items()}
    out["ratio"] = out["vector_env_steps_per_s"] / out["trivial_steps_per_s"]
    # what the env adds to each step, on top of SB3's own per-step cost
    out["env_us_per_step"] = 1e6 * (1 / out["vector_env_steps_per_s"] - 1 / out["trivial_steps_per_s"])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int_at_least(256), default=20_000,
                    help="learning steps per measurement (default 20000)")
    ap.add_argument("--repeats", type=int_at_least(1), default=3, help="measurements per env, median kept (default 3)")
    ap.add_argument("--settings", default=",".join(SETTINGS), help=f"comma list of {SETTINGS} (default both)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a key of configs/vector_ff.yaml for the config setting, e.g. n_envs=16")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_training.json")
    args = ap.parse_args(argv)
    settings = [s.strip() for s in args.settings.split(",") if s.strip()]
    bad = [s for s in settings if s not in SETTINGS]
    if bad or not settings:
        raise UserError(f"--settings {args.settings!r}: expected a comma list of {SETTINGS}")

    from ssbl_pb.analysis.report import write_json
    from ssbl_pb.files import check_output_path
    from ssbl_pb.training.config import load_config, parse_overrides

    check_output_path(args.out, is_dir=False)
    overrides = parse_overrides(args.set)
    load_config(ROOT / "configs" / "vector_ff.yaml", overrides)  # unknown keys and bad values fail here

    results = {"steps": args.steps, "repeats": args.repeats, "overrides": overrides}
    for s in settings:
        r = measure(s, args.steps, overrides, args.repeats)
        results[s] = r
        print(f"{s:7s} trivial env {r['trivial_steps_per_s']:6.0f} steps/s, Vector env "
              f"{r['vector_env_steps_per_s']:6.0f} steps/s: {r['ratio']:.0%} "
              f"({'PASS' if r['ratio'] >= 0.8 else 'MISS'} >= 80 %); env adds {r['env_us_per_step']:.0f} us/step; "
              f"as a plain gym env in DummyVecEnv {r['vector_env_dummy_steps_per_s']:6.0f} steps/s")
    write_json(args.out, results)
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
