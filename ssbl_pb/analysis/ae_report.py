"""The files ``tools/train_ae.py`` writes for a trained autoencoder (checkpoint, history, figures, summary)."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import UserError
from ..files import write_json, write_text
from ..perception.autoencoding.ae_losses import triplet_centres
from ..perception.autoencoding.ae_plots import keypoint_overlay, plot_losses, reconstructions
from ..perception.autoencoding.ae_train import save_checkpoint, split_centres
from ..perception.autoencoding.autoencoders import SAEV, Autoencoder
from .frames import frames_hfov
from .video import save_png


def example_frames(data: dict[str, np.ndarray], n: int = 6) -> np.ndarray:
    """``n`` held-out frames with the most members in view (spread over the validation episodes)."""
    try:
        _, val = split_centres(data["episode"], 10)
    except UserError:  # too few episodes to hold any out (a smoke run): show any
        val = triplet_centres(data["episode"])
    visible = np.isfinite(data["members_px"][val, :, 0]).sum(axis=1)
    order = val[np.argsort(-visible, kind="stable")]
    picked: list[int] = []
    for i in order:  # not two frames of one episode when avoidable
        if all(data["episode"][i] != data["episode"][j] for j in picked):
            picked.append(int(i))
        if len(picked) == n:
            break
    for i in order:
        if len(picked) == n:
            break
        if int(i) not in picked:
            picked.append(int(i))
    return data["frames"][np.asarray(picked, dtype=int)]


def write_report(out: Path, model: Autoencoder, history: list[dict[str, float]], data: dict[str, np.ndarray],
                 extra: dict[str, Any]) -> dict[str, Any]:
    """encoder.pt, history.csv, losses.png, reconstructions.png, keypoints.png (SAEV) and summary.json."""
    summary = {"arch": model.arch, "size": model.size.name, "resolution": model.size.input_size,
               "feature_dim": model.feature_dim, "steps": int(history[-1]["step"]),
               "train_seconds": history[-1]["seconds"], "frames": int(len(data["frames"])),
               "final_val": {k[4:]: v for k, v in history[-1].items() if k.startswith("val_")},
               "camera_hfov_deg": frames_hfov(data), **extra}
    save_checkpoint(out / "encoder.pt", model, {"summary": summary})
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(history[0]))
    writer.writeheader()
    writer.writerows(history)
    write_text(out / "history.csv", buf.getvalue())
    plot_losses(history, out / "losses.png", f"{model.arch} ({model.size.name})")
    frames = example_frames(data)
    save_png(out / "reconstructions.png", reconstructions(model, frames))
    if isinstance(model, SAEV):
        save_png(out / "keypoints.png", keypoint_overlay(model, frames))
    write_json(out / "summary.json", summary)
    return summary
