"""Figures of a trained autoencoder: loss curves, reconstructions, and keypoints on their frames (paper Fig. 7)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch

from ...files import atomic_write
from .autoencoders import SAEV, Autoencoder, keypoint_pixels, to_input


def _save_fig(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, bbox_inches="tight"))
    plt.close(fig)
    return path


def plot_losses(history: list[dict[str, float]], path: Path, title: str = "") -> Path:
    """Training (dashed) and validation (solid) loss parts against steps, log scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    steps = [r["step"] for r in history]
    parts = [k[4:] for k in history[0] if k.startswith("val_")]
    for i, part in enumerate(parts):
        colour = f"C{i}"
        ax.plot(steps, [r[f"val_{part}"] for r in history], color=colour, label=f"{part} (validation)")
        ax.plot(steps, [r[f"train_{part}"] for r in history], color=colour, ls="--", alpha=0.6)
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("loss (dashed: training)")
    ax.set_title(title)
    ax.legend(fontsize=7)
    return _save_fig(fig, path)


def _upscale(img: np.ndarray, side: int) -> np.ndarray:
    return cv2.resize(img, (side, side), interpolation=cv2.INTER_NEAREST)


def reconstructions(model: Autoencoder, frames: np.ndarray, scale: int = 3) -> np.ndarray:
    """Two rows: the frames (uint8, (n, S, S, 3)) and their reconstructions, upscaled to ``scale * S``."""
    with torch.inference_mode():
        recon, _ = model.eval()(to_input(torch.from_numpy(np.ascontiguousarray(frames))))
    out = (recon.clamp(0, 1).permute(0, 2, 3, 1).numpy() * 255).round().astype(np.uint8)
    side = scale * frames.shape[1]
    top = np.concatenate([_upscale(f, side) for f in frames], axis=1)
    bottom = np.concatenate([_upscale(f, side) for f in out], axis=1)
    return np.concatenate([top, bottom], axis=0)


def keypoint_colours(k: int) -> np.ndarray:
    """One distinct RGB colour (uint8) per keypoint, consistent across frames (as in Fig. 7)."""
    hsv = np.stack([np.linspace(0, 179, k, endpoint=False), np.full(k, 230), np.full(k, 255)], axis=1)
    return cv2.cvtColor(hsv.astype(np.uint8)[None], cv2.COLOR_HSV2RGB)[0]


def keypoint_overlay(model: SAEV, frames: np.ndarray, scale: int = 4, min_presence: float = 0.0) -> np.ndarray:
    """Frames side by side with each SAEV keypoint drawn at its pixel, one colour per keypoint (paper Fig. 7);
    the dot's radius grows with presence, keypoints below ``min_presence`` are drawn as rings."""
    with torch.inference_mode():
        code = model.eval().code(to_input(torch.from_numpy(np.ascontiguousarray(frames))))
    uv = keypoint_pixels(code[..., :2], model.size).numpy()
    rho = code[..., 2].numpy()
    colours = keypoint_colours(code.shape[1])
    tiles = []
    for f, pts, pres in zip(frames, uv, rho, strict=True):
        t = np.ascontiguousarray(_upscale(f, scale * f.shape[0]))
        for (u, v), r, c in zip(pts, pres, colours, strict=True):
            centre = (int(round((u + 0.5) * scale)), int(round((v + 0.5) * scale)))
            radius = 2 + int(round(4 * float(r)))
            cv2.circle(t, centre, radius, tuple(int(x) for x in c), -1 if r >= min_presence else 1, cv2.LINE_AA)
        tiles.append(t)
    gap = np.full((tiles[0].shape[0], 4, 3), 255, np.uint8)
    return np.concatenate([x for t in tiles for x in (t, gap)][:-1], axis=1)
