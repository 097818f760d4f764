#!/usr/bin/env python
"""Training throughput: PPO (default config) on the Vector env vs on a trivial env with the same observation and
action sizes, in one run. Writes results/bench_training.json.
    python tools/bench_training.py --steps 40000
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=40_000)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_training.json")
    ap.add_argument("--sb3-defaults", action="store_true",
                    help="PPO with SB3's default settings and one env instead of configs/vector_ff.yaml")
    args = ap.parse_args(argv)

    import gymnasium as gym
    import numpy as np
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from ssbl_pb.env.observation import OBS_SIZE
    from ssbl_pb.report import write_json
    from ssbl_pb.training.config import load_config
    from ssbl_pb.training.run import build_model, make_vec_env

    class Trivial(gym.Env):
        observation_space = gym.spaces.Box(-10, 10, (OBS_SIZE,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            self.t = 0
            return self.observation_space.sample(), {}

        def step(self, action):
            self.t += 1
            return self.observation_space.sample(), 0.0, False, self.t >= 150, {}

    cfg = load_config(ROOT / "configs" / "vector_ff.yaml")
    torch.set_num_threads(cfg.torch_threads)
    label = "SB3 defaults, 1 env" if args.sb3_defaults else "configs/vector_ff.yaml"
    out = {"steps": args.steps, "n_envs": 1 if args.sb3_defaults else cfg.n_envs, "config": label}
    for name in ("trivial", "vector_env"):
        if args.sb3_defaults:
            from stable_baselines3 import PPO

            from ssbl_pb.env.approach import make_env

            venv = DummyVecEnv([Trivial if name == "trivial" else make_env])
            model = PPO("MlpPolicy", venv, device="cpu")
        else:
            if name == "trivial":
                venv = VecNormalize(DummyVecEnv([Trivial] * cfg.n_envs), gamma=cfg.ppo.gamma)
            else:
                venv = make_vec_env(cfg, 0)
            model = build_model(cfg, venv, Path("/tmp/ssbl_bench_tb"))
            model.tensorboard_log = None
        t0 = time.perf_counter()
        model.learn(args.steps)
        out[f"{name}_steps_per_s"] = model.num_timesteps / (time.perf_counter() - t0)
        venv.close()
    out["ratio"] = out["vector_env_steps_per_s"] / out["trivial_steps_per_s"]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.out, out)
    print(f"{label}: trivial env {out['trivial_steps_per_s']:.0f} steps/s, "
          f"Vector env {out['vector_env_steps_per_s']:.0f} steps/s: {out['ratio']:.0%} "
          f"({'PASS' if out['ratio'] >= 0.8 else 'MISS'} >= 80 %) -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
