"""Training throughput (``tools/bench_training.py``, docs/benchmarks.md "Speed"): PPO on the Vector env against PPO
on a trivial env with the same observation and action sizes, in SB3's own defaults (``sb3``) and in our training
config (``config``); the tool's docstring says what each setting runs."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from ..core.observation import OBS_SIZE
from ..env.gymenv.approach import make_env
from ..training import run
from ..training.config import load_config
from ..training.vec_env import BatchedVecEnv

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "vector_ff.yaml"


def _trivial_env_class():  # noqa: ANN202
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
    import torch  # heavy: only when measuring
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    cfg = load_config(CONFIG, overrides)
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
