"""Autoencoder losses (paper III-B; weights from the original code, shared/reference/peppersocial.md):
reconstruction 1.0, Finn's smoothness 0.001 and presence 0.1 (SAEV only, as ``(rho - 1)^2``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch
from torch.nn import functional as F

from ...errors import UserError
from .autoencoders import Autoencoder, downsample


@dataclasses.dataclass(frozen=True)
class LossWeights:
    reconstruction: float = 1.0
    smoothness: float = 0.001  # the original's; tools/train_ae.py --smoothness-weight
    presence: float = 0.1  # SAEV only; the conv AE's code has no presence

    def __post_init__(self) -> None:
        for name, v in dataclasses.asdict(self).items():
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise UserError(f"--{name}-weight {v!r}: expected a finite number >= 0")


def smoothness(prev: torch.Tensor, cur: torch.Tensor, nxt: torch.Tensor) -> torch.Tensor:
    """Finn et al.'s smoothness: the squared second difference of the code over frames t-1, t, t+1.

    SAEV codes (B, K, 3) use (x, y) only, summed over the two and averaged over batch and keypoints (as the
    code does); flat codes (B, F) are summed over F and averaged over the batch."""
    if cur.dim() == 3:
        prev, cur, nxt = prev[..., :2], cur[..., :2], nxt[..., :2]
    return ((cur - prev) - (nxt - cur)).pow(2).sum(dim=-1).mean()


def triplet_loss(model: Autoencoder, triplet: torch.Tensor, weights: LossWeights | None = None
                 ) -> tuple[torch.Tensor, dict[str, float]]:
    """Total loss of a batch of frame triplets (B, 3, 3, S, S) in [0, 1]; returns it and its parts.

    The reconstruction is of the middle frame, at the model's ``recon_size``."""
    w = weights or LossWeights()
    b = triplet.shape[0]
    frames = triplet.reshape(b * 3, *triplet.shape[2:])
    code = model.code(frames)
    code = code.reshape(b, 3, *code.shape[1:])
    recon = model.decode(code[:, 1])
    target = downsample(triplet[:, 1], model.size.recon_size)
    parts = {"reconstruction": F.mse_loss(recon, target),
             "smoothness": smoothness(code[:, 0], code[:, 1], code[:, 2])}
    total = w.reconstruction * parts["reconstruction"] + w.smoothness * parts["smoothness"]
    if model.arch == "saev":
        parts["presence"] = (code[:, 1, :, 2] - 1.0).pow(2).mean()
        total = total + w.presence * parts["presence"]
    return total, {k: float(v.detach()) for k, v in parts.items()} | {"total": float(total.detach())}


def triplet_centres(episode: np.ndarray) -> np.ndarray:
    """Indices t whose frames t-1, t, t+1 belong to one episode (the smoothness loss needs all three)."""
    e = np.asarray(episode)
    t = np.arange(1, len(e) - 1)
    return t[(e[t - 1] == e[t]) & (e[t + 1] == e[t])]
