"""Training runs: build the vectorised envs and the model, train with callbacks, resume from checkpoints.

A run directory holds ``config.yaml``, ``model.zip`` + ``vecnormalize.pkl`` (final), ``best/`` (best evaluation,
with its normalisation), ``checkpoints/``, ``learning_curve.csv/png``, ``eval.csv``, ``baselines.json``,
``tb/`` (TensorBoard) and ``summary.json``.
"""

from __future__ import annotations

import functools
import json
import math
import pickle
import shutil
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from sb3_contrib import RecurrentPPO
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

from ..agents.policies import make_policy
from ..agents.rollout import run_episode
from ..agents.trained import STEP_STAMP, resolve_model
from ..cli import DeferredSignals
from ..core.actions import ActionStages
from ..env.gymenv.approach import core_kwargs, make_env
from ..env.gymenv.encoded import EncodedVecEnv, load_encoder
from ..env.gymenv.wrappers import ActionStagesWrapper
from ..errors import UserError
from ..files import check_output_path, output_dir, remove_temporaries, source_commit, write_text
from ..params import ConfigError, parse_yaml
from .callbacks import (
    EpisodeLogCallback,
    EvalCheckpointCallback,
    ProgressCallback,
    RewardRampCallback,
    StopOnSignal,
    save_checkpoint,
    save_model,
)
from .config import TrainConfig, load_config, save_config
from .config import env_kwargs as _env_kwargs
from .curves import plot_learning_curve
from .policies import bounded_policy
from .vec_env import BatchedVecEnv

# what a run directory holds: all that tools/train_pb.py writes there, and all --overwrite may remove
RUN_ENTRIES = ("config.yaml", "baselines.json", "model.zip", "vecnormalize.pkl", "best", "checkpoints",
               "learning_curve.csv", "learning_curve.png", "eval.csv", "tb", "summary.json")
# what reading a saved model or normalisation raises when the file is corrupt or not one (not our bugs)
LOAD_ERRORS = (OSError, EOFError, ValueError, KeyError, RuntimeError, ImportError, AttributeError,
               pickle.UnpicklingError, zipfile.BadZipFile)


class RunError(UserError):
    """A run directory cannot be used (no checkpoint, corrupt files); the message names the path."""


def is_run_dir(path: Path) -> bool:
    """``path`` holds a run of this tool: its ``config.yaml`` is a mapping of training settings, or it holds only
    the first checkpoint (a run killed in the moment between that and its ``config.yaml``)."""
    try:
        cfg = parse_yaml((path / "config.yaml").read_text())
    except (OSError, ValueError, yaml.YAMLError):
        return _only_checkpoints(path)
    return isinstance(cfg, dict) and {"obs_mode", "ppo"} <= set(cfg)


def _only_checkpoints(path: Path) -> bool:
    ckpts = path / "checkpoints"
    return ([p.name for p in path.iterdir()] == ["checkpoints"] and ckpts.is_dir()
            and all(p.is_file() and (p.name.startswith(("ckpt_", ".ckpt_", ".latest.")) or p.name == "latest.json")
                    for p in ckpts.iterdir()))


def remove_run(run_dir: Path) -> None:
    """Remove what a run wrote into ``run_dir`` (``RUN_ENTRIES`` and temporaries), and nothing else."""
    for name in RUN_ENTRIES:
        p = run_dir / name
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        elif p.exists() or p.is_symlink():
            p.unlink()
    clean_temporaries(run_dir)


def clean_temporaries(run_dir: Path) -> None:
    """Remove what a killed run left half-written: temporary files of its own names and ``best/``'s stages
    (a ``best/`` caught between its two renames is put back)."""
    remove_temporaries(run_dir, lambda name: name in RUN_ENTRIES, folders=("best",))
    remove_temporaries(run_dir / "best", lambda name: name in RUN_ENTRIES + ("eval.json",))
    remove_temporaries(run_dir / "checkpoints", lambda name: name == "latest.json" or name.startswith("ckpt_"))


class EnvFactory:
    """Picklable env constructor for SubprocVecEnv workers (the agent's action smoothing included)."""

    def __init__(self, kwargs: dict[str, Any], monitor: bool = True, smoothing: float = 1.0,
                 shield: bool = False, shield_at_place: bool = False, shield_penalty: float = 0.0) -> None:
        self.kwargs, self.monitor, self.smoothing, self.shield = kwargs, monitor, smoothing, shield
        self.shield_at_place, self.shield_penalty = shield_at_place, shield_penalty

    def __call__(self) -> Any:
        env = make_env(**self.kwargs)
        if self.shield or self.smoothing < 1.0:
            stages = ActionStages.of(env.unwrapped, self.smoothing, self.shield, self.shield_at_place)
            env = ActionStagesWrapper(env, stages, self.shield_penalty)
        if self.monitor:
            env = Monitor(env, info_keywords=("is_success",))
        return env


class BatchedFactory:
    """``BatchedVecEnv(n)`` for env keyword arguments (``_env_kwargs``) with the config's action stages."""

    def __init__(self, kwargs: dict[str, Any], cfg: TrainConfig) -> None:
        self.env_kwargs, _ = core_kwargs(**{k: v for k, v in kwargs.items() if k != "obs_mode"})
        self.smoothing, self.shield, self.at_place = cfg.action_smoothing, cfg.shield_active, cfg.shield_at_place
        self.penalty = cfg.shield_penalty

    def __call__(self, n: int) -> Any:
        return BatchedVecEnv(n, self.smoothing, self.shield, self.at_place, self.penalty, **self.env_kwargs)


def make_vec_env(cfg: TrainConfig, seed: int) -> Any:
    """The training VecEnv (batched, Dummy or Subproc, ``cfg.vec_env_kind``), seeded, with VecNormalize."""
    kind = cfg.vec_env_kind
    if kind == "batched":
        venv = VecMonitor(BatchedFactory(_env_kwargs(cfg), cfg)(cfg.n_envs), info_keywords=("is_success",))
    else:
        factory = EnvFactory(_env_kwargs(cfg), smoothing=cfg.action_smoothing, shield=cfg.shield_active,
                             shield_at_place=cfg.shield_at_place, shield_penalty=cfg.shield_penalty)
        fns = [factory] * cfg.n_envs
        venv = SubprocVecEnv(fns, start_method="forkserver") if kind == "subproc" else DummyVecEnv(fns)
    venv.seed(seed)
    if cfg.encoder_file:  # frozen autoencoder: all envs' images encoded in one batch per step (env.gymenv.encoded)
        venv = EncodedVecEnv(venv, load_encoder(cfg.encoder_file, cfg.camera_size), cfg.feature_smoothing)
    if cfg.policy_obs_mode == "vector":
        return VecNormalize(venv, norm_obs=cfg.standardises_obs, norm_reward=True, gamma=cfg.ppo.gamma)
    if cfg.obs_mode == "camera_speed":
        return VecNormalize(venv, norm_obs=cfg.standardises_obs, norm_obs_keys=["speed"], norm_reward=True,
                            gamma=cfg.ppo.gamma)
    return VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=cfg.ppo.gamma)


def _algo(cfg: TrainConfig) -> Any:
    return RecurrentPPO if cfg.policy == "lstm" else PPO


def build_model(cfg: TrainConfig, venv: Any, tb_dir: Path) -> Any:
    p = cfg.ppo
    kwargs: dict[str, Any] = {"net_arch": list(p.net_arch), "log_std_init": p.log_std_init}
    if cfg.policy == "lstm":
        kwargs["lstm_hidden_size"] = p.lstm_hidden_size
        names = {"vector": "MlpLstmPolicy", "camera": "CnnLstmPolicy", "camera_speed": "MultiInputLstmPolicy"}
    else:
        names = {"vector": "MlpPolicy", "camera": "CnnPolicy", "camera_speed": "MultiInputPolicy"}
    policy: Any = names[cfg.policy_obs_mode]
    if p.bounded_mean:
        policy = bounded_policy(cfg.policy_obs_mode, cfg.policy == "lstm")
    lr: Any = p.learning_rate
    if p.learning_rate_end is not None:
        lr = LinearSchedule(p.learning_rate, p.learning_rate_end, 1.0)
    return _algo(cfg)(policy, venv, learning_rate=lr, n_steps=p.n_steps,
                      batch_size=p.batch_size, n_epochs=p.n_epochs, gamma=p.gamma, gae_lambda=p.gae_lambda,
                      clip_range=p.clip_range, ent_coef=p.ent_coef, vf_coef=p.vf_coef,
                      max_grad_norm=p.max_grad_norm, policy_kwargs=kwargs, seed=cfg.seed, device=cfg.device,
                      tensorboard_log=str(tb_dir), verbose=0)


def baseline_returns(cfg: TrainConfig) -> dict[str, float]:
    """Mean episode return of the random and SFFM policies on the training task (same reward weights)."""
    kwargs = {**_env_kwargs(cfg), "obs_mode": "vector"}
    kwargs["reward"] = {**kwargs["reward"], **{k: v[1] for k, v in cfg.reward_ramp.items()}}  # as evaluations
    out = {}
    for name in ("random", "sffm"):
        env = make_env(**kwargs)
        core = env.unwrapped
        pol = make_policy(name, core.robot_params, core.social, seed=cfg.seed)
        rets = [run_episode(env, pol, cfg.eval_seed + 50_000 + i, keep_trajectory=False).metrics["return"]
                for i in range(cfg.baseline_episodes)]
        env.close()
        out[name] = float(np.mean(rets))
    return out


def _callbacks(cfg: TrainConfig, run_dir: Path) -> list[Any]:
    eval_kwargs = _env_kwargs(cfg)  # evaluated with the ramps' final weights, comparable across the run
    if cfg.encoder_file:
        eval_kwargs["encoder"] = cfg.encoder_file
        eval_kwargs["feature_smoothing"] = cfg.feature_smoothing
    eval_kwargs["reward"] = {**eval_kwargs["reward"], **{k: v[1] for k, v in cfg.reward_ramp.items()}}
    ramp = [RewardRampCallback(cfg.reward_ramp, cfg.reward_ramp_fraction, cfg.total_steps)] if cfg.reward_ramp else []
    return ramp + [ProgressCallback(cfg.total_steps), EpisodeLogCallback(run_dir / "learning_curve.csv"),
            EvalCheckpointCallback(run_dir, EnvFactory(eval_kwargs, monitor=False, shield_at_place=cfg.shield_at_place),
                                   cfg.eval_every,
                                   cfg.eval_episodes, cfg.eval_seed, cfg.checkpoint_every, cfg.policy == "lstm",
                                   cfg.action_smoothing, cfg.shield_active,
                                   BatchedFactory(eval_kwargs, cfg) if cfg.vec_env_kind == "batched" else None)]


@functools.cache
def process_commit() -> str | None:
    """The commit of the code this process runs: the checkout's at the first call (a recipe's later stages run the
    code its first stage loaded, whatever the checkout holds by then)."""
    return source_commit()


def _learn(cfg: TrainConfig, run_dir: Path, model: Any, venv: Any, resumed_from: int | None) -> dict[str, Any]:
    """Train to ``cfg.total_steps``. Ctrl-C / SIGTERM stop at the next env step: a checkpoint is saved, the
    ``--resume`` command printed, and the signal re-raised (exit 130 / 143 through ``cli.run``)."""
    start_steps, t0 = model.num_timesteps, time.perf_counter()
    remaining = max(0, cfg.total_steps - model.num_timesteps)
    with DeferredSignals() as signals:  # also covers the final saves: a signal then waits for them
        try:
            model.learn(remaining, callback=[*_callbacks(cfg, run_dir), StopOnSignal(signals)],
                        reset_num_timesteps=False, tb_log_name="ppo")
        finally:
            venv.close()
        norm = model.get_vec_normalize_env()
        step = save_checkpoint(model, norm, run_dir)  # the finished state is resumable too (--total-steps)
        if signals.signum is not None and step < cfg.total_steps:
            print(f"saved a checkpoint at step {step}; continue with: python tools/train_pb.py --resume {run_dir}",
                  file=sys.stderr)
            signals.raise_if_signalled()
        wall = time.perf_counter() - t0
        save_model(model, norm, run_dir)  # model.zip and vecnormalize.pkl, stamped with the step
        baselines = json.loads((run_dir / "baselines.json").read_text())
        plot_learning_curve(run_dir, baselines)
        best = run_dir / "best" / "eval.json"
        summary = {"name": cfg.name, "steps": int(model.num_timesteps), "total_steps": cfg.total_steps,
                   "commit": process_commit(), "resumed_from": resumed_from, "wall_time_s": round(wall, 1),
                   "steps_per_s": round((model.num_timesteps - start_steps) / max(wall, 1e-9), 1),
                   "baselines": baselines, "best_eval": json.loads(best.read_text()) if best.exists() else None}
        write_text(run_dir / "summary.json", json.dumps(summary, indent=2))
        signals.raise_if_signalled()  # a signal during the final saves: the run is complete, exit as asked
    return summary


def check_new_run(cfg: TrainConfig, run_dir: Path, overwrite: bool = False, init_from: Path | None = None) -> None:
    """Every check a new run needs, made before anything is written: the output path, the env the config
    describes (scenario, room, robot, social and task values) and the run to start from."""
    check_output_path(run_dir, "--out")
    if (run_dir / "config.yaml").exists() and not overwrite:
        raise RunError(f"{run_dir}: already holds a run; continue it with --resume {run_dir}, start it again with "
                       f"--overwrite, or choose another --out")
    if overwrite and run_dir.is_dir() and any(run_dir.iterdir()) and not is_run_dir(run_dir):
        raise RunError(f"--out {run_dir}: holds files but no training run (no config.yaml of tools/train_pb.py); "
                       f"--overwrite replaces only a run directory: choose a new or empty folder")
    make_env(**_env_kwargs(cfg)).close()
    if init_from is not None:
        check_init_source(cfg, init_from)


def check_init_source(cfg: TrainConfig, source: Path) -> None:
    """``--init-from``: a run with a model, its normalisation and a config of the same kind."""
    if not (source / "config.yaml").is_file():
        raise RunError(f"--init-from {source}: not a run directory (no config.yaml)")
    _, norm, _ = resolve_model(str(source))
    if norm is None:
        raise RunError(f"--init-from {source}: no vecnormalize.pkl to start from")
    src = load_config(source / "config.yaml")
    for key in ("obs_mode", "policy", "encoder"):
        if getattr(src, key) != getattr(cfg, key):
            raise RunError(f"--init-from {source}: its {key} is {getattr(src, key)!r}, this config's is "
                           f"{getattr(cfg, key)!r}; fine-tuning needs the same")
    if tuple(src.ppo.net_arch) != tuple(cfg.ppo.net_arch):
        raise RunError(f"--init-from {source}: its ppo.net_arch is {list(src.ppo.net_arch)}, this config's is "
                       f"{list(cfg.ppo.net_arch)}; fine-tuning needs the same network")


def train(cfg: TrainConfig, run_dir: Path, overwrite: bool = False, init_from: Path | None = None
          ) -> dict[str, Any]:
    """Start a new run in ``run_dir`` (refuses a directory that already holds a run unless ``overwrite``, which
    first removes that run's files, ``RUN_ENTRIES``, and nothing else; a folder holding other files but no run is
    refused).

    ``init_from`` (a run directory) starts from that run's final weights and normalisation instead of from
    scratch (fine-tuning, e.g. with other reward weights or scenarios); the step counter starts at 0.
    The run is resumable from its first second: the model is built before anything is written, and its initial
    state (checkpoint 0) is the first file, before ``config.yaml``, which makes the folder a run; if anything
    fails while setting up, the run directory is removed again."""
    check_new_run(cfg, run_dir, overwrite, init_from)
    torch.set_num_threads(cfg.torch_threads)
    venv = make_vec_env(cfg, cfg.seed)
    try:
        model = build_model(cfg, venv, run_dir / "tb")
        if init_from is not None:
            venv = _init_from(model, venv, init_from, cfg.ppo.restart_std)
        if run_dir.is_dir():  # the old run (--overwrite), else the temporaries a run killed before config.yaml left
            (remove_run if overwrite else clean_temporaries)(run_dir)
        with output_dir(run_dir, "--out"):
            save_checkpoint(model, venv, run_dir)
            save_config(cfg, run_dir / "config.yaml")
            write_baselines(cfg, run_dir)
    except BaseException:
        venv.close()
        raise
    return _learn(cfg, run_dir, model, venv, None)


def write_baselines(cfg: TrainConfig, run_dir: Path) -> None:
    """``baselines.json``: the random and SFFM returns the learning curve is drawn against."""
    write_text(run_dir / "baselines.json", json.dumps(baseline_returns(cfg), indent=2))


def _init_from(model: Any, venv: Any, source: Path, restart_std: float | None = None) -> Any:
    """Copy a run's final policy weights and observation statistics into a fresh model and VecEnv; with
    ``restart_std``, the action std restarts at that value."""
    src_model, src_norm, _ = resolve_model(str(source))
    if src_norm is None:
        raise RunError(f"{source}: no vecnormalize.pkl to start from")
    algo = _algo(load_config(source / "config.yaml"))
    try:  # only reading the files: a failure after them is a bug and keeps its traceback
        params = algo.load(str(src_model), device="cpu").get_parameters()
        with open(src_norm, "rb") as fh:
            new = pickle.load(fh)
    except LOAD_ERRORS as exc:
        raise RunError(f"--init-from {source}: cannot read its model ({type(exc).__name__}: {exc})") from exc
    inputs = (new.observation_space.shape, venv.venv.observation_space.shape)
    policy = _match_action_head(params["policy"], model.policy.state_dict(), *widened(*inputs))
    model.set_parameters({"policy": policy}, exact_match=False)
    if restart_std is not None:
        with torch.no_grad():
            model.policy.log_std.fill_(math.log(restart_std))
    if widened(*inputs) != (0, 0):
        _widen_normalisation(new, venv.venv)
    if new.observation_space != venv.venv.observation_space:
        raise RunError(f"--init-from {source}: its observations are {new.observation_space}, this config's are "
                       f"{venv.venv.observation_space}")
    new.set_venv(venv.venv)
    new.training, new.norm_reward = True, venv.norm_reward
    model.set_env(new)
    return new


def widened(source: tuple[int, ...], target: tuple[int, ...]) -> tuple[int, int]:
    """(old, new) input sizes when a Vector policy of ``source`` observation shape is fine-tuned on a longer
    Vector observation ``target`` (the range scan appended); (0, 0) otherwise."""
    if len(source) == 1 and len(target) == 1 and source[0] < target[0]:
        return source[0], target[0]
    return 0, 0


def _match_action_head(source: dict[str, Any], target: dict[str, Any], old_inputs: int = 0, new_inputs: int = 0
                       ) -> dict[str, Any]:
    """Rename the action head's weights between a plain and a bounded-mean policy (``action_net.weight`` <->
    ``action_net.0.weight``) so fine-tuning across the two keeps them; with ``old_inputs`` < ``new_inputs``, the
    layers reading the observation get zero weights for the entries appended to it (the fine-tuned policy starts
    acting exactly as the source, blind to them); raise when layers still do not match."""
    out = dict(source)
    for key, w in list(out.items()):
        t = target.get(key)
        if (old_inputs and t is not None and w.ndim == 2 and t.ndim == 2 and w.shape[0] == t.shape[0]
                and (w.shape[1], t.shape[1]) == (old_inputs, new_inputs)):
            out[key] = torch.cat([w, torch.zeros(w.shape[0], new_inputs - old_inputs, dtype=w.dtype)], dim=1)
    for key in list(out):
        for a, b in (("action_net.", "action_net.0."), ("action_net.0.", "action_net.")):
            if key.startswith(a) and key not in target and b + key[len(a):] in target:
                out[b + key[len(a):]] = out.pop(key)
                break
    missing = sorted(k for k in target if k not in out)
    bad = sorted(k for k in target if k in out and tuple(out[k].shape) != tuple(target[k].shape))
    if missing or bad:
        raise RunError(f"the source policy does not fit this config's network (missing {missing}, different shapes "
                       f"{bad}): use the same ppo.net_arch and observation mode")
    return out


WIDEN_SAMPLES = 300  # steps of random actions per copy to measure the appended entries' mean and variance


def _widen_normalisation(norm: Any, venv: Any) -> None:
    """Extend a loaded ``VecNormalize``'s observation statistics to ``venv``'s longer Vector observation: the
    appended entries get the mean and variance measured over ``WIDEN_SAMPLES`` steps of random actions (their
    running statistics would otherwise move at the pace of the source's millions of counted steps)."""
    old = norm.observation_space.shape[0]
    rows = [venv.reset()]
    for _ in range(WIDEN_SAMPLES):
        rows.append(venv.step(np.stack([venv.action_space.sample() for _ in range(venv.num_envs)]))[0])
    extra = np.concatenate(rows)[:, old:].astype(np.float64)
    rms = norm.obs_rms
    rms.mean = np.concatenate([rms.mean, extra.mean(axis=0)])
    rms.var = np.concatenate([rms.var, np.maximum(extra.var(axis=0), 1e-4)])
    norm.observation_space = venv.observation_space


def latest_checkpoint(run_dir: Path) -> tuple[Path, Path, int]:
    latest = run_dir / "checkpoints" / "latest.json"
    if not latest.is_file():  # a model alone (shipped, copied) is no run to start over: a new run starts from it
        how = f"a new run with --init-from {run_dir} --out NEW_DIR" if (run_dir / "model.zip").is_file() else \
            f"the run again with --overwrite --out {run_dir}"
        raise RunError(f"{run_dir}: no checkpoint to resume from (expected {latest}); start {how}")
    try:
        info = json.loads(latest.read_text())
    except (OSError, ValueError) as exc:
        raise RunError(f"{latest}: unreadable checkpoint index ({exc})") from exc
    name, step = (info.get("model"), info.get("step")) if isinstance(info, dict) else (None, None)
    if not (isinstance(name, str) and name.endswith(".zip") and Path(name).name == name
            and isinstance(step, int) and not isinstance(step, bool) and step >= 0):
        raise RunError(f"{latest}: unreadable checkpoint index: expected {{\"step\": N, \"model\": "
                       f"\"ckpt_N.zip\"}}, got {json.dumps(info)[:80]}")
    model = run_dir / "checkpoints" / name
    norm = model.with_name(model.stem + "_vecnormalize.pkl")
    for f in (model, norm):
        if not f.is_file():
            raise RunError(f"{run_dir}: checkpoint file missing: {f}")
    return model, norm, step


def resume(run_dir: Path, total_steps: int | None = None) -> dict[str, Any]:
    """Continue a run from its last checkpoint: step counter, optimiser state and normalisation intact."""
    if not (run_dir / "config.yaml").is_file():
        hint = "; it was killed as it was created: start it again with the same command" if (
            run_dir.is_dir() and _only_checkpoints(run_dir)) else ""
        raise RunError(f"{run_dir}: not a run directory (no config.yaml){hint}")
    cfg = load_config(run_dir / "config.yaml", None if total_steps is None else {"total_steps": total_steps})
    model_path, norm_path, step = latest_checkpoint(run_dir)
    if step >= cfg.total_steps and finished_at(run_dir) == step:
        raise RunError(f"{run_dir}: already finished ({step} of {cfg.total_steps} steps); nothing changed. To train "
                       f"it longer: --resume {run_dir} --total-steps N with N > {step}")
    torch.set_num_threads(cfg.torch_threads)
    venv = make_vec_env(cfg, cfg.seed + step)
    try:
        try:
            venv = VecNormalize.load(str(norm_path), venv.venv)
            model = _algo(cfg).load(str(model_path), env=venv, device=cfg.device,
                                    tensorboard_log=str(run_dir / "tb"))
        except LOAD_ERRORS as exc:
            raise RunError(f"{model_path}: cannot load the checkpoint ({type(exc).__name__}: {exc})") from exc
        stamp = vars(venv).get(STEP_STAMP, step)  # checkpoints saved before the stamp have none
        if model.num_timesteps != step or stamp != step:
            raise RunError(f"{model_path}: holds {model.num_timesteps} steps, its normalisation {stamp}, its index "
                           f"says {step}")
        clean_temporaries(run_dir)
        _truncate_log(run_dir / "learning_curve.csv", step)
        _truncate_log(run_dir / "eval.csv", step)
        if not (run_dir / "baselines.json").is_file():  # killed while setting up
            write_baselines(cfg, run_dir)
    except BaseException:
        venv.close()
        raise
    return _learn(cfg, run_dir, model, venv, step)


def finished_at(run_dir: Path) -> int | None:
    """The step ``summary.json`` records the run finished at (None: not finished, or unreadable)."""
    try:
        steps = json.loads((run_dir / "summary.json").read_text())["steps"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return steps if isinstance(steps, int) else None


def _truncate_log(path: Path, step: int) -> None:
    """Drop log lines written after the checkpoint (they will be produced again)."""
    lines = path.read_text().splitlines() if path.exists() else []
    if not lines:
        path.unlink(missing_ok=True)
        return

    def before(line: str) -> bool:
        head = line.split(",")[0]
        return head.isdigit() and int(head) <= step and len(line.split(",")) == len(lines[0].split(","))

    keep = [lines[0]] + [ln for ln in lines[1:] if before(ln)]
    write_text(path, "\n".join(keep) + "\n")


__all__ = ["ConfigError", "RunError", "TrainConfig", "load_config", "resume", "train"]
