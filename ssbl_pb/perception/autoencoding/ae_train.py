"""Training the camera autoencoders on frame triplets, and their checkpoints (``tools/train_ae.py``).

Batches are frame triplets (t-1, t, t+1) of one episode (the smoothness loss needs all three); every tenth
episode is held out for validation. A checkpoint records the architecture, the size and the input resolution,
and loading checks each against what the caller needs, so an encoder never meets frames it was not made for.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ...errors import UserError
from ...files import atomic_write
from .ae_losses import LossWeights, triplet_centres, triplet_loss
from .autoencoders import ARCHS, AESize, Autoencoder, build, get_size, to_input

FORMAT = 1


class CheckpointError(UserError):
    """An encoder checkpoint is missing, unreadable or not the one needed; the message names both values."""


@dataclasses.dataclass(frozen=True)
class AETrainParams:
    """Training settings. The original used Adam at lr 1e-5 for ~1500 epochs of ~3000 triplets on a GPU; on 2
    CPU cores we train a few thousand steps at lr 1e-3 (docs/decisions.md, "Camera state representations")."""

    steps: int = 3000
    batch: int = 32  # frame triplets (original: 32)
    lr: float = 1e-3
    eval_every: int = 250
    val_every_episode: int = 10  # every tenth episode is held out
    seed: int = 0
    weights: LossWeights = dataclasses.field(default_factory=LossWeights)

    def __post_init__(self) -> None:
        for name in ("steps", "batch", "eval_every", "val_every_episode"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise UserError(f"--{name.replace('_', '-')} {v!r}: expected an integer >= 1")
        if not (isinstance(self.lr, int | float) and 0 < self.lr < 1):
            raise UserError(f"--lr {self.lr!r}: expected a number in (0, 1)")


def split_centres(episode: np.ndarray, every: int, strict: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Triplet centres of the training and the validation episodes (every ``every``-th episode: numbers
    ``every - 1``, ``2 every - 1``, ...). Too few episodes to hold one out (or to keep one for training) is a
    ``UserError`` naming how many are needed; with ``strict=False`` a warning, and validation on the training
    episodes."""
    c = triplet_centres(episode)
    val = (np.asarray(episode)[c] % every) == every - 1
    if val.all() or not val.any():
        n = len(np.unique(np.asarray(episode)[c]))
        what = "none is held out for validation" if not val.any() else "all are held out for validation"
        msg = (f"the frames hold {n} episode(s) of three or more frames and {what} (one episode in {every}, "
               f"numbers {every - 1}, {2 * every - 1}, ...): collect at least {every} episodes "
               f"(tools/collect_frames.py --episodes {every})")
        if strict:
            raise UserError(msg)
        warnings.warn(msg + "; validating on the training episodes instead", UserWarning, stacklevel=2)
        return c, c
    return c[~val], c[val]


def triplets(frames: torch.Tensor, centres: np.ndarray) -> torch.Tensor:
    """uint8 frames (N, S, S, 3) at ``centres - 1, centres, centres + 1`` -> float (B, 3, 3, S, S) in [0, 1]."""
    idx = torch.as_tensor(np.stack([centres - 1, centres, centres + 1], axis=1).ravel())
    x = to_input(frames[idx])
    return x.reshape(len(centres), 3, *x.shape[1:])


def evaluate_loss(model: Autoencoder, frames: torch.Tensor, centres: np.ndarray, weights: LossWeights,
                  batch: int = 64) -> dict[str, float]:
    """Mean loss parts over ``centres`` in eval mode (no dropout, BatchNorm running statistics)."""
    was = model.training
    model.eval()
    sums: dict[str, float] = {}
    with torch.inference_mode():
        for i in range(0, len(centres), batch):
            c = centres[i:i + batch]
            _, parts = triplet_loss(model, triplets(frames, c), weights)
            for k, v in parts.items():
                sums[k] = sums.get(k, 0.0) + v * len(c)
    model.train(was)
    return {k: v / len(centres) for k, v in sums.items()}


RESUMED = ("batch", "lr", "eval_every", "val_every_episode", "seed")  # what a resumed run must share


def train_autoencoder(data: dict[str, np.ndarray], arch: str, size: str | AESize, params: AETrainParams,
                      progress: Any = None, max_val: int = 512,
                      on_eval: Callable[[int, Autoencoder, dict[str, Any]], None] | None = None,
                      resume: str | Path | None = None) -> tuple[Autoencoder, list[dict[str, float]]]:
    """Train a fresh ``arch`` autoencoder on a frames file's arrays; returns it (eval mode) and its history
    (one row per ``eval_every`` steps: step, seconds, training parts averaged since the last row, validation
    parts on up to ``max_val`` held-out triplets). ``on_eval(step, model, state)``, when given, runs after each
    row (model in eval mode; training resumes after it): ``state`` is what ``resume`` needs, so a checkpoint
    saved with ``{"resume": state}`` as its extra (a snapshot) continues exactly where it was written: the same
    weights, optimiser moments, random streams and history as an uninterrupted run."""
    torch.manual_seed(params.seed)
    rng = np.random.default_rng(params.seed)
    model = build(arch, size)
    s = model.size.input_size
    if data["frames"].shape[1] != s:
        raise UserError(f"frames are {data['frames'].shape[1]}x{data['frames'].shape[1]}, the {model.size.name} "
                        f"encoder takes {s}x{s}")
    frames = torch.from_numpy(np.ascontiguousarray(data["frames"]))
    if len(triplet_centres(data["episode"])) == 0:
        raise UserError("the frames hold no triplet of consecutive frames of one episode")
    # tools/train_ae.py refuses too few episodes up front (split_centres); callers here get a warning
    train_c, val_c = split_centres(data["episode"], params.val_every_episode, strict=False)
    val_c = rng.permutation(val_c)[:max_val]
    opt = torch.optim.Adam(model.parameters(), lr=params.lr)
    history: list[dict[str, float]] = []
    start, offset = 1, 0.0
    if resume is not None:
        state = resume_state(resume, model.arch, model.size.name, params, len(frames))
        model.load_state_dict(read_checkpoint(resume)["state_dict"])
        opt.load_state_dict(state["optimizer"])
        rng.bit_generator.state = state["numpy_rng"]
        torch.set_rng_state(state["torch_rng"])
        history = [dict(r) for r in state["history"]]
        start, offset = int(state["step"]) + 1, float(history[-1]["seconds"]) if history else 0.0
    acc: dict[str, float] = {}
    t0, n_acc = time.perf_counter(), 0
    model.train()
    for step in range(start, params.steps + 1):
        batch = triplets(frames, rng.choice(train_c, params.batch))
        loss, parts = triplet_loss(model, batch, params.weights)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        for k, v in parts.items():
            acc[k] = acc.get(k, 0.0) + v
        n_acc += 1
        if progress is not None:
            progress.update(1)
        if step % params.eval_every == 0 or step == params.steps:
            val = evaluate_loss(model, frames, val_c, params.weights)
            row = {"step": step, "seconds": round(offset + time.perf_counter() - t0, 1)}
            row |= {f"train_{k}": v / n_acc for k, v in acc.items()} | {f"val_{k}": v for k, v in val.items()}
            history.append(row)
            acc, n_acc = {}, 0
            if progress is not None and hasattr(progress, "set_postfix_str"):
                progress.set_postfix_str(f"val loss {val['total']:.4f}")
            if on_eval is not None:
                model.eval()
                state = {"step": step, "optimizer": opt.state_dict(), "numpy_rng": rng.bit_generator.state,
                         "torch_rng": torch.get_rng_state(), "history": [dict(r) for r in history],
                         "params": {k: getattr(params, k) for k in RESUMED}, "frames": len(frames),
                         "weights": dataclasses.asdict(params.weights)}
                on_eval(step, model, state)
                model.train()
    return model.eval(), history


def resume_state(path: str | Path, arch: str, size: str, params: AETrainParams, n_frames: int) -> dict[str, Any]:
    """A snapshot's resume state, checked against the run it is to continue (``arch``, ``size`` name, settings,
    number of frames); errors name ``--resume``. Cheap: tools check it before any work or output."""
    blob = read_checkpoint(path, "--resume")
    state = blob["extra"].get("resume")
    if not isinstance(state, dict):
        raise CheckpointError(f"--resume {path}: holds no training state (tools/train_ae.py --snapshot-every "
                              f"writes snapshots that do)")
    for what, have, want in (("architecture", blob["arch"], arch), ("size", blob["size"], size),
                             ("number of frames", state.get("frames"), n_frames),
                             ("loss weights", state.get("weights", dataclasses.asdict(LossWeights())),
                              dataclasses.asdict(params.weights)),
                             *((k, state["params"].get(k), getattr(params, k)) for k in RESUMED)):
        if have != want:
            raise CheckpointError(f"--resume {path}: {what} is {have!r}, this run's is {want!r}")
    if not state["step"] < params.steps:
        raise CheckpointError(f"--resume {path}: already at step {state['step']}, --steps is {params.steps}")
    return state


# -- checkpoints ---------------------------------------------------------------------------------------------
def save_checkpoint(path: str | Path, model: Autoencoder, extra: dict[str, Any] | None = None) -> Path:
    """Write the model with its architecture, size and input resolution, atomically (temporary file, rename)."""
    blob = {"format": FORMAT, "arch": model.arch, "size": model.size.name,
            "size_fields": dataclasses.asdict(model.size), "resolution": model.size.input_size,
            "state_dict": model.state_dict(), "extra": extra or {}}
    return atomic_write(path, lambda tmp: torch.save(blob, tmp))


def read_checkpoint(path: str | Path, flag: str = "encoder checkpoint") -> dict[str, Any]:
    """A checkpoint's contents; errors start with ``flag`` and the path (e.g. ``--resume FILE: ...``)."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{flag} {path}: file not found (tools/train_ae.py writes one)")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # a torch archive that is not ours, a truncated file, ... (torch's text: load advice)
        what = "a zip archive but no whole torch file" if zipfile.is_zipfile(path) else "not a torch file"
        raise CheckpointError(f"{flag} {path}: unreadable, {what} (expected an autoencoder checkpoint of "
                              f"tools/train_ae.py)") from exc
    if not isinstance(blob, dict) or blob.get("format") != FORMAT or blob.get("arch") not in ARCHS:
        raise CheckpointError(f"{flag} {path}: not an autoencoder checkpoint of tools/train_ae.py")
    return blob


def load_autoencoder(path: str | Path, arch: str | None = None, size: str | None = None,
                     resolution: int | None = None) -> Autoencoder:
    """A trained autoencoder in eval mode; ``arch``, ``size`` and ``resolution``, when given, must match."""
    blob = read_checkpoint(path)
    for what, want, have in (("architecture", arch, blob["arch"]), ("size", size, blob["size"]),
                             ("input resolution", resolution, blob["resolution"])):
        if want is not None and want != have:
            raise CheckpointError(f"encoder checkpoint {path}: {what} is {have!r}, expected {want!r}")
    fields = dict(blob["size_fields"])
    for k, v in fields.items():
        if isinstance(v, list):
            fields[k] = tuple(v)
    s = AESize(**fields)
    if blob["size"] in ("paper", "cpu") and s != get_size(blob["size"]):
        raise CheckpointError(f"encoder checkpoint {path}: size {blob['size']!r} has layers {s}, this version's "
                              f"{blob['size']!r} is {get_size(blob['size'])}; retrain it with tools/train_ae.py")
    model = build(blob["arch"], s)
    try:
        model.load_state_dict(blob["state_dict"])
    except RuntimeError as exc:
        raise CheckpointError(f"encoder checkpoint {path}: weights do not fit the {blob['arch']} network "
                              f"({exc})") from exc
    return model.eval()


def checkpoint_info(path: str | Path, flag: str = "encoder checkpoint") -> dict[str, Any]:
    """Architecture, size name, input resolution and extra metadata of a checkpoint (without building it)."""
    blob = read_checkpoint(path, flag)
    return {k: blob[k] for k in ("arch", "size", "resolution", "extra")}

