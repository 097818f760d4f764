"""The paper's Table I regenerated: every state representation x network trained and evaluated alike.

Stage 1 (once per table): first-person frames from a mix of policies, then the SAEV and conv autoencoders
(``perception``), unless checkpoints are given. Stage 2 (``RowTrial``: one row and seed, a trial of the sweeps'
machinery, so rows run on a local process pool or a Ray cluster and a killed table resumes where it stopped):
PPO / RecurrentPPO on the row's observation with the frozen encoder, then the best model evaluated on held-out
seeds. Every row uses the same task (scenario ``default``, the paper's two-person group), reward, action
smoothing and no safety shield (the paper had none; camera modes could not use it). The frozen encoders'
features reach the policy raw (``normalize_obs`` off; the vector rows keep VecNormalize's standardisation):
standardising divides each feature by its running spread and blows up near-constant ones, and every camera row
piloted trained far better raw (docs/decisions.md, "Camera state representations", ``normalize_obs``).

Every row trains with the default config's reward and its jerk-cost ramp (configs/vector_ff.yaml: without the
ramp PPO learns nothing, docs/decisions.md "Smoothness"). Because the ramp changes the reward during training,
a row's reward is the best of its periodic evaluations (deterministic, fixed seeds, final weights) instead of
the paper's best smoothed training reward, which a ramp inflates early on; the latter is kept as
``train_smoothed_best`` (weight ``Budget.smoothing`` on the past). The random policy's reward is its mean return
on the same evaluation seeds. Percentage (``performance_calculator.py`` in the original): 100 (value - random) /
(Vector+LSTM - random), per seed, then mean and spread over seeds.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..agents.rollout import run_episodes
from ..env.gymenv.encoded import encoder_hfov
from ..errors import UserError
from ..params import load_yaml
from ..perception.autoencoding.ae_train import AETrainParams, CheckpointError, checkpoint_info, train_autoencoder
from ..perception.autoencoding.autoencoders import SIZES
from ..training.config import TrainConfig, load_config
from ..training.run import train
from .ae_report import write_report
from .evaluation import Setup
from .frames import collect, load_frames, save_frames
from .table1_rows import BASELINE, BUDGETS, ROWS, Budget, Row

BENCH_SEED = 500_000  # held-out evaluation seeds (docs/decisions.md, "Training")


def get_budget(name: str) -> Budget:
    if name not in BUDGETS:
        raise UserError(f"--budget {name!r}: expected one of {sorted(BUDGETS)}")
    return BUDGETS[name]


def find_row(label_or_slug: str) -> Row:
    for r in ROWS:
        if label_or_slug in (r.label, r.slug):
            return r
    raise UserError(f"row {label_or_slug!r}: expected one of {[r.slug for r in ROWS]}")


def smoothed_best(returns: list[float] | np.ndarray, weight: float) -> float:
    """Best value of the running average ``s = weight * s + (1 - weight) * r`` (started at the first return)."""
    r = np.asarray(returns, dtype=float)
    if not len(r):
        return float("nan")
    s, best = r[0], r[0]
    for x in r[1:]:
        s = weight * s + (1.0 - weight) * x
        best = max(best, s)
    return float(best)


def percent(value: float, random: float, baseline: float) -> float:
    """Table I's percentage: 0 % is the random policy, 100 % the Vector+LSTM baseline."""
    return 100.0 * (value - random) / (baseline - random)


# -- stage 1: encoders ---------------------------------------------------------------------------------------
def check_given_encoders(given: dict[str, str | None], camera_hfov_deg: float | None = None) -> None:
    """Refuse, naming the flag (``--saev`` / ``--conv``), a given checkpoint that is missing, unreadable, of
    another architecture or learned through another camera than ``camera_hfov_deg``: before any output exists."""
    for arch, path in given.items():
        if not path:
            continue
        flag = f"--{arch} {path}"
        try:
            have = checkpoint_info(path)["arch"]
            hfov = encoder_hfov(path)
        except CheckpointError as exc:  # its message names the file as "encoder checkpoint PATH: ..."
            text = str(exc).removeprefix(f"encoder checkpoint {path}: ")
            raise UserError(f"{flag}: {text}") from None
        if have != arch:
            raise UserError(f"{flag}: holds a {have} autoencoder, not {arch}")
        if camera_hfov_deg is not None and abs(hfov - camera_hfov_deg) > 1e-3:
            raise UserError(f"{flag}: learned through a {hfov:g} deg camera, the table asks for --camera-hfov "
                            f"{camera_hfov_deg:g} (give a matching encoder, or that --camera-hfov)")


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes (an encoder checkpoint: a trial's result depends on its weights)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def prepare_encoders(budget: Budget, out: Path, archs: set[str], given: dict[str, str | None], seed: int = 0,
                     progress: Any = None, camera_hfov_deg: float | None = None) -> dict[str, str]:
    """Checkpoint path per architecture in ``archs``: given ones as they are, else trained into
    ``out/ae/ARCH`` (frames in ``out/frames.npz``, seen through a camera of ``camera_hfov_deg``, default
    Pepper's), reusing what an earlier run of the table left there. An encoder that learned through another
    camera than ``camera_hfov_deg`` (when given) is refused."""
    paths: dict[str, str] = {}
    frames_file = out / "frames.npz"
    for arch in sorted(archs):
        ckpt = Path(given[arch]) if given.get(arch) else out / "ae" / arch / "encoder.pt"
        if given.get(arch) and not ckpt.is_file():
            raise UserError(f"--{arch} {ckpt}: file not found (expected a tools/train_ae.py checkpoint)")
        if not ckpt.is_file():
            if not frames_file.is_file():
                save_frames(frames_file, collect(budget.frames_episodes, SIZES["cpu"].input_size, seed,
                                                 camera_hfov_deg=camera_hfov_deg))
            data = load_frames(frames_file)
            params = AETrainParams(steps=budget.ae_steps, seed=seed, eval_every=max(1, min(250, budget.ae_steps)))
            model, history = train_autoencoder(data, arch, "cpu", params, progress)
            (out / "ae" / arch).mkdir(parents=True, exist_ok=True)
            write_report(out / "ae" / arch, model, history, data, {"frames_file": str(frames_file)})
        have = encoder_hfov(ckpt)
        if camera_hfov_deg is not None and abs(have - camera_hfov_deg) > 1e-3:
            raise UserError(f"{arch} encoder {ckpt}: learned through a {have:g} deg camera, the table asks for "
                            f"--camera-hfov {camera_hfov_deg:g} (give another --out or a matching encoder)")
        paths[arch] = str(given[arch]) if given.get(arch) else str(ckpt.resolve())
    return paths


# -- stage 2: one row ----------------------------------------------------------------------------------------
def _default_reward() -> dict[str, Any]:
    """The default training config's reward keys (configs/vector_ff.yaml): weights and ramp."""
    cfg = load_yaml(Path(__file__).resolve().parents[2] / "configs" / "vector_ff.yaml")
    return {k: cfg[k] for k in ("reward", "reward_ramp", "reward_ramp_fraction") if k in cfg}


def table_reward() -> dict[str, Any]:
    """The reward every row trains with, resolved as the training config holds it (``reward``, ``reward_ramp``,
    ``reward_ramp_fraction``, defaults filled in): what a trial's definition records and its run trains with."""
    cfg = load_config(None, _default_reward())
    return json.loads(json.dumps({"reward": cfg.reward, "reward_ramp": cfg.reward_ramp,
                                  "reward_ramp_fraction": cfg.reward_ramp_fraction}))


def features_raw(row: Row) -> bool:
    """Whether a row's observation reaches the policy unstandardised: a frozen encoder's features do."""
    return row.encoder in ("conv", "saev")


def row_config(row: Row, seed: int, budget: Budget, encoders: dict[str, str], feature_smoothing: float = 1.0,
               reward: dict[str, Any] | None = None) -> dict[str, Any]:
    """The training config (``training.config`` keys) of a row (``feature_smoothing``: the camera rows' low-pass
    of the encoded features, ``env.gymenv.encoded``; 1 = off; ``reward``: the reward keys, default
    ``_default_reward()``)."""
    reward = _default_reward() if reward is None else reward
    cfg: dict[str, Any] = {**reward, "normalize_obs": not features_raw(row),
        "name": f"{row.slug}_s{seed}", "obs_mode": row.obs_mode, "encoder": row.encoder, "policy": row.policy,
        "scenario": "default", "seed": seed, "n_envs": budget.n_envs, "safety_shield": False,
        "total_steps": budget.vector_steps if row.obs_mode == "vector" else budget.camera_steps,
        "eval_every": budget.eval_every, "eval_episodes": budget.eval_episodes,
        "checkpoint_every": budget.eval_every, "baseline_episodes": 2,
        "ppo": {"n_steps": budget.n_steps, "batch_size": min(256, budget.n_steps * budget.n_envs)}}
    if row.encoder in ("conv", "saev"):
        cfg["encoder_checkpoint"] = encoders[row.encoder]
        cfg["camera_size"] = int(checkpoint_info(encoders[row.encoder])["resolution"])
        if feature_smoothing != 1.0:
            cfg["feature_smoothing"] = feature_smoothing
    return cfg


def _test_episodes(spec: str, episodes: int, seed: int = BENCH_SEED, reward: dict | None = None
                   ) -> dict[str, float]:
    res = run_episodes(Setup(spec, env_kwargs=(("reward", reward or {}),)), range(seed, seed + episodes))
    return {"success_rate": float(np.mean([r.metrics["success"] for r in res])),
            "mean_return": float(np.mean([r.metrics["return"] for r in res])),
            # the part of the return the jerk cost takes (our addition to eq. 15; docs/decisions.md "Smoothness")
            "jerk_cost": float(-np.mean([r.metrics["term_smoothness"] for r in res]))}


def _column(path: Path, name: str) -> list[float]:
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return [float(r[name]) for r in csv.DictReader(fh)]


def run_row(row: Row, seed: int, budget: Budget, run_dir: Path, encoders: dict[str, str] | None = None,
            feature_smoothing: float = 1.0, reward: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train (into ``run_dir``, a normal run directory) and evaluate one row for one seed (``reward``: the reward
    keys, default ``_default_reward()``)."""
    t0 = time.perf_counter()
    if row.obs_mode == "random":
        cfg = load_config(None, row_config(BASELINE, seed, budget, {}, reward=reward))
        final = {**cfg.reward, **{k: v[1] for k, v in cfg.reward_ramp.items()}}  # as the evaluations
        evals = _test_episodes("random", budget.eval_episodes, TrainConfig.eval_seed, final)
        test = _test_episodes("random", budget.test_episodes)
        result = {"reward": evals["mean_return"], "steps": 0, **test}
    else:
        cfg = load_config(None, row_config(row, seed, budget, encoders or {}, feature_smoothing, reward))
        summary = train(cfg, run_dir, overwrite=True)
        returns = _column(run_dir / "learning_curve.csv", "return")
        evals = _column(run_dir / "eval.csv", "mean_return")
        best = run_dir / "best"
        test = _test_episodes(str(best if (best / "model.zip").is_file() else run_dir), budget.test_episodes)
        result = {"reward": max(evals) if evals else test["mean_return"], "steps": summary["steps"],
                  "train_smoothed_best": smoothed_best(returns, budget.smoothing), "evaluations": len(evals),
                  "run": str(run_dir), "train_steps_per_s": summary["steps_per_s"], **test}
    return result | {"row": row.label, "seed": seed, "budget": budget.name,
                     "seconds": round(time.perf_counter() - t0, 1)}


@dataclasses.dataclass(frozen=True)
class RowTrial:
    """One row and seed as a trial of ``ssbl_pb.sweep.run_trials`` (the sweeps' machinery: a local process pool
    or a Ray cluster, resumable; its run directory is ``ROOT/trials/SLUG,seed=S/``)."""

    row: Row
    seed: int
    budget: Budget
    encoders: tuple[tuple[str, str], ...] = ()  # (arch, checkpoint path) the camera rows use
    threads: int = 1  # torch threads in the trial's process (does not change what it computes)
    feature_smoothing: float = 1.0  # the camera rows' low-pass of the encoded features (1 = off)
    reward: str = ""  # the reward trained with (``table_reward()``) as JSON; "" = read it when run
    encoder_sha256: str = ""  # of the row's encoder checkpoint ("" = none, or not hashed)

    @property
    def name(self) -> str:
        return f"{self.row.slug},seed={self.seed}"

    def _reward(self) -> dict[str, Any]:
        return json.loads(self.reward) if self.reward else table_reward()

    def definition(self) -> dict[str, Any]:
        """What the result depends on: a changed reward (configs/vector_ff.yaml) or encoder file is a new trial."""
        return {"kind": "table1_row", "row": self.row.label, "seed": self.seed,
                "budget": dataclasses.asdict(self.budget), "encoder": dict(self.encoders).get(self.row.encoder),
                "normalize_obs": not features_raw(self.row), "reward": self._reward()} | (
                    {"encoder_sha256": self.encoder_sha256} if self.encoder_sha256 else {}) | (
                    {"feature_smoothing": self.feature_smoothing}
                    if self.feature_smoothing != 1.0 and features_raw(self.row) else {})

    def upgrade(self, stored: dict[str, Any], record: dict[str, Any], trial_dir: Path) -> dict[str, Any]:
        """A result stored before definitions held the reward and the encoder's hash, completed from what its run
        left: the reward in its run's config.yaml, and this encoder's hash if the file is no newer than the
        result (so an unchanged table keeps its finished rows; anything else runs again)."""
        if "reward" in stored:
            return stored
        out = dict(stored)
        if self.row.obs_mode == "random":
            return out  # no run to read the reward from: it runs again (evaluations only, quick)
        try:
            config = load_yaml(trial_dir / "config.yaml")
        except UserError:
            return out
        out["reward"] = {k: config[k] for k in ("reward", "reward_ramp", "reward_ramp_fraction") if k in config}
        encoder = stored.get("encoder")
        if encoder and self.encoder_sha256:
            finished = time.mktime(time.strptime(record.get("finished", "1970-01-01T00:00:00"), "%Y-%m-%dT%H:%M:%S"))
            if Path(encoder).is_file() and Path(encoder).stat().st_mtime <= finished:
                out["encoder_sha256"] = file_sha256(encoder)
        return out

    def __call__(self, trial_dir: Path) -> dict[str, Any]:
        import torch

        torch.set_num_threads(max(1, self.threads))
        return run_row(self.row, self.seed, self.budget, trial_dir, dict(self.encoders), self.feature_smoothing,
                       self._reward())


def row_trials(rows: list[Row], seeds: int, budget: Budget, encoders: dict[str, str], threads: int = 1,
               feature_smoothing: float = 1.0) -> list[RowTrial]:
    """Every row x seed ``0 .. seeds-1`` (seed-major: a seed's rows finish together, its percentages first), each
    defined by the reward read now and its encoder file's hash (where the file exists)."""
    enc = tuple(sorted(encoders.items()))
    reward = json.dumps(table_reward(), sort_keys=True)
    hashes = {arch: file_sha256(path) for arch, path in encoders.items() if Path(path).is_file()}
    return [RowTrial(row, seed, budget, enc, threads, feature_smoothing, reward, hashes.get(row.encoder, ""))
            for seed in range(seeds) for row in rows]
