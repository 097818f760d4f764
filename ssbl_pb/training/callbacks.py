"""SB3 callbacks: progress bar, episode log (learning curve), periodic evaluation with best model, checkpoints."""

from __future__ import annotations

import csv
import json
import math
import shutil
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from ..agents.rollout import run_episode
from ..agents.trained import STEP_STAMP, TrainedPolicy
from ..cli import make_bar
from ..core.shield import ShieldParams
from ..files import atomic_write_all, make_stage_dir, replace_dir, write_text
from .vec_env import evaluate_first_episodes


class ProgressCallback(BaseCallback):
    """Progress bar (``cli.make_bar``) with env steps/s and the success rate of the last 100 training episodes."""

    def __init__(self, total: int) -> None:
        super().__init__()
        self.total = total
        self.success: deque[float] = deque(maxlen=100)

    def _on_training_start(self) -> None:
        self.bar = make_bar(self.total, "train", "step", initial=self.num_timesteps)
        self.t0, self.n0 = time.perf_counter(), self.num_timesteps

    def _on_step(self) -> bool:
        for info, done in zip(self.locals["infos"], self.locals["dones"], strict=False):
            if done and "is_success" in info:
                self.success.append(float(info["is_success"]))
        if self.num_timesteps > self.bar.total:  # PPO collects whole rollouts: the last one may pass the total
            self.bar.total = self.num_timesteps
        self.bar.update(self.num_timesteps - self.bar.n)
        if self.n_calls % 50 == 0:
            rate = (self.num_timesteps - self.n0) / max(time.perf_counter() - self.t0, 1e-9)
            succ = f"{np.mean(self.success):.0%}" if self.success else "-"
            self.bar.set_postfix_str(f"{rate:.0f} steps/s, success {succ}")
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


class EpisodeLogCallback(BaseCallback):
    """Appends (step, return, length, success) of every finished training episode to ``learning_curve.csv``."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path

    def _on_training_start(self) -> None:
        new = not self.path.exists()
        self.fh = open(self.path, "a", newline="")
        self.writer = csv.writer(self.fh)
        if new:
            self.writer.writerow(["step", "return", "length", "success"])

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            ep = info.get("episode")
            if ep is not None:
                self.writer.writerow([self.num_timesteps, f"{ep['r']:.5f}", ep["l"], int(info.get("is_success", 0))])
                self.fh.flush()
        return True

    def _on_training_end(self) -> None:
        self.fh.close()


class EvalCheckpointCallback(BaseCallback):
    """Every ``eval_every`` steps: evaluate on fixed seeds (deterministic), keep the best model with its
    normalisation in ``best/``; every ``checkpoint_every`` steps: a resumable checkpoint."""

    def __init__(self, run_dir: Path, make_eval_env: Any, eval_every: int, eval_episodes: int, eval_seed: int,
                 checkpoint_every: int, recurrent: bool, smoothing: float = 1.0, shield: bool = False,
                 make_eval_venv: Any = None) -> None:
        """``make_eval_venv(n)``, when given, builds a seedable ``BatchedVecEnv`` of ``n`` copies (smoothing and
        shield inside) that plays all evaluation episodes at once instead of ``make_eval_env`` one by one."""
        super().__init__()
        self.run_dir = run_dir
        self.make_eval_env, self.make_eval_venv = make_eval_env, make_eval_venv
        self.eval_every, self.eval_episodes, self.eval_seed = eval_every, eval_episodes, eval_seed
        self.checkpoint_every = checkpoint_every
        self.recurrent = recurrent
        self.smoothing, self.shield = smoothing, shield
        self.best = -math.inf
        state = run_dir / "best" / "eval.json"
        if state.exists():
            self.best = json.loads(state.read_text())["score"]
        self.last_eval = self.last_ckpt = None

    def _on_training_start(self) -> None:
        self.last_eval = self.num_timesteps // self.eval_every
        self.last_ckpt = self.num_timesteps // self.checkpoint_every

    def evaluate(self) -> dict[str, float]:
        if self.make_eval_venv is not None:
            venv = self.make_eval_venv(self.eval_episodes)
            venv.seed(self.eval_seed)
            success, returns = evaluate_first_episodes(self.model, self.training_env, self.recurrent, venv)
            return {"step": self.num_timesteps, "success_rate": float(success.mean()),
                    "mean_return": float(returns.mean())}

        env = self.make_eval_env()
        core = env.unwrapped  # the shield brakes within the training env's robot limits, as in training
        at_place = getattr(self.make_eval_env, "shield_at_place", False)  # the config's (EnvFactory)
        policy = TrainedPolicy(self.model, self.training_env, self.recurrent, self.smoothing, self.shield,
                               ShieldParams.of(core, at_place))
        try:
            res = [run_episode(env, policy, self.eval_seed + i, keep_trajectory=False).metrics
                   for i in range(self.eval_episodes)]
        finally:
            env.close()
        return {"step": self.num_timesteps, "success_rate": float(np.mean([r["success"] for r in res])),
                "mean_return": float(np.mean([r["return"] for r in res]))}

    def _on_step(self) -> bool:
        if self.num_timesteps // self.eval_every > self.last_eval:
            self.last_eval = self.num_timesteps // self.eval_every
            ev = self.evaluate()
            self.logger.record("eval/success_rate", ev["success_rate"])
            self.logger.record("eval/mean_return", ev["mean_return"])
            path = self.run_dir / "eval.csv"
            new = not path.exists()
            with open(path, "a") as fh:
                if new:
                    fh.write("step,success_rate,mean_return\n")
                fh.write(f"{ev['step']},{ev['success_rate']:.4f},{ev['mean_return']:.5f}\n")
            score = ev["success_rate"] + 1e-3 * ev["mean_return"]
            if score > self.best:
                self.best = score
                self.save(self.run_dir / "best", ev | {"score": score})
        if self.num_timesteps // self.checkpoint_every > self.last_ckpt:
            self.last_ckpt = self.num_timesteps // self.checkpoint_every
            self.checkpoint()
        return True

    def save(self, folder: Path, ev: dict[str, float]) -> None:
        """The best model so far, as one unit: model, normalisation, config and ``eval.json`` (the score the next
        best must beat) are written into a temporary folder that then replaces ``folder`` (``files.replace_dir``),
        so a kill leaves the old set or the new one, never parts of both."""
        stage = make_stage_dir(folder.parent, f".{folder.name}.new-")
        try:
            save_model(self.model, self.training_env, stage)
            cfg = self.run_dir / "config.yaml"
            if cfg.exists():
                write_text(stage / "config.yaml", cfg.read_text())
            write_text(stage / "eval.json", json.dumps(ev, indent=2))
            replace_dir(stage, folder)
        finally:
            if stage.exists():
                shutil.rmtree(stage, ignore_errors=True)

    def checkpoint(self) -> None:
        save_checkpoint(self.model, self.training_env, self.run_dir)


def save_model(model: Any, vec_normalize: Any, folder: Path, stem: str = "model",
               norm_name: str = "vecnormalize.pkl") -> None:
    """``folder/{stem}.zip`` and its normalisation, written together (``files.atomic_write_all``); the
    normalisation carries the model's step (``STEP_STAMP``), so a pair from two saves is refused when loaded."""
    setattr(vec_normalize, STEP_STAMP, int(model.num_timesteps))
    atomic_write_all({folder / f"{stem}.zip": lambda p: model.save(p),
                      folder / norm_name: lambda p: vec_normalize.save(str(p))})


def save_checkpoint(model: Any, vec_normalize: Any, run_dir: Path) -> int:
    """A resumable checkpoint named by step; ``latest.json`` points at it only once its files are complete."""
    n = int(model.num_timesteps)
    folder = run_dir / "checkpoints"
    save_model(model, vec_normalize, folder, f"ckpt_{n:09d}", f"ckpt_{n:09d}_vecnormalize.pkl")
    write_text(folder / "latest.json", json.dumps({"step": n, "model": f"ckpt_{n:09d}.zip"}))
    return n


class StopOnSignal(BaseCallback):
    """Ends ``learn`` at the next env step once a deferred SIGINT/SIGTERM arrived (``cli.DeferredSignals``)."""

    def __init__(self, signals: Any) -> None:
        super().__init__()
        self.signals = signals

    def _on_step(self) -> bool:
        return self.signals.signum is None


class RewardRampCallback(BaseCallback):
    """Ramps reward weights linearly with training progress (set in every env at each rollout start)."""

    def __init__(self, ramp: dict[str, list[float]], fraction: float, total: int) -> None:
        super().__init__()
        self.ramp, self.fraction, self.total = ramp, fraction, total

    def weights_at(self, step: int) -> dict[str, float]:
        x = min(1.0, step / (self.fraction * self.total))
        return {k: float(a + (b - a) * x) for k, (a, b) in self.ramp.items()}

    def _on_rollout_start(self) -> None:
        w = self.weights_at(self.num_timesteps)
        venv = self.training_env.unwrapped
        if hasattr(venv, "envs"):  # DummyVecEnv
            for env in venv.envs:
                env.unwrapped.set_reward_weights(**w)
        else:  # SubprocVecEnv: the call is forwarded through the wrappers in each worker
            venv.env_method("set_reward_weights", **w)
        for k, v in w.items():
            self.logger.record(f"reward_ramp/{k}", v)

    def _on_step(self) -> bool:
        return True
