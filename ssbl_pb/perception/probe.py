"""Linear probe: do an encoder's features carry the humans? (issue 13's "keypoints carry the humans" target)

A linear map (ridge regression on standardised features, one per member slot: members keep their colour, so a
slot is one person's appearance) is fitted on training frames from the features to each visible member's
position relative to the robot, and scored on held-out frames: the distance between predicted and true
positions, over every visible member of every held-out frame.
"""

from __future__ import annotations

import numpy as np


def fit_linear(x: np.ndarray, y: np.ndarray, ridge: float = 1e-2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ridge fit of ``y`` (n, d) on ``x`` (n, f): returns (mean, scale, weights) for ``predict_linear``."""
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-6
    z = np.column_stack([(x - mean) / scale, np.ones(len(x))])
    reg = ridge * len(x) * np.eye(z.shape[1])
    reg[-1, -1] = 0.0  # the bias is not penalised
    w = np.linalg.solve(z.T @ z + reg, z.T @ y)
    return mean, scale, w


def predict_linear(model: tuple[np.ndarray, np.ndarray, np.ndarray], x: np.ndarray) -> np.ndarray:
    mean, scale, w = model
    return np.column_stack([(x - mean) / scale, np.ones(len(x))]) @ w


def member_probe(feat_train: np.ndarray, members_train: np.ndarray, feat_test: np.ndarray,
                 members_test: np.ndarray, ridge: float = 1e-2) -> dict[str, float]:
    """Median / 90th-percentile error (m) of per-slot linear maps features -> visible member positions.

    ``members_*`` (N, M, 2): robot-frame positions of the members in view, NaN otherwise."""
    errors = []
    for m in range(members_train.shape[1]):
        tr, te = np.isfinite(members_train[:, m, 0]), np.isfinite(members_test[:, m, 0])
        if tr.sum() < feat_train.shape[1] + 2 or not te.any():
            continue
        fit = fit_linear(feat_train[tr], members_train[tr, m], ridge)
        errors.append(np.linalg.norm(predict_linear(fit, feat_test[te]) - members_test[te, m], axis=1))
    e = np.concatenate(errors) if errors else np.zeros(0)
    return {"median_m": float(np.median(e)) if len(e) else float("nan"),
            "p90_m": float(np.percentile(e, 90)) if len(e) else float("nan"), "scored": int(len(e))}


def visible_members(data: dict[str, np.ndarray]) -> np.ndarray:
    """Members' robot-frame positions where their torso is in the image, NaN elsewhere (frames file arrays)."""
    out = data["members_rel"].astype(float).copy()
    out[~np.isfinite(data["members_px"][..., 0])] = np.nan
    return out
