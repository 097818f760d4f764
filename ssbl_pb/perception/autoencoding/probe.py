"""Linear probe: do an encoder's features carry the humans? (the "keypoints carry the humans" target)

A linear map (ridge regression on standardised features, one per member slot: members keep their colour, so a
slot is one person's appearance) is fitted on training frames from the features to each visible member's
position relative to the robot, and scored on held-out frames: the distance between predicted and true
positions, over every visible member of every held-out frame, split into its depth (the robot's x) and
lateral (y) parts. Two reference rows bound it: a constant per member (the training mean) and the members' true
torso pixels, each slot from its own pixel (``pixel_probe``): what a perfect keypoint on every member gives a
linear map, whose depth error stays large because a torso's pixel says little about its distance.

``reader="mlp"`` replaces the linear map by a small MLP (two hidden layers of ``MLP_HIDDEN``, ELU; Adam): whether
the features carry the members at all, read nonlinearly. From the true torso pixels it reads the position to a
centimetre (depth is ``f (torso height - camera height) / row offset``, exact but not linear).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

READERS = ("linear", "mlp")
MLP_HIDDEN = 128  # ours: enough for 48-256 features and ~20k sightings; ~10 s per member slot on one core
MLP_EPOCHS = 60


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


def fit_predict_mlp(x: np.ndarray, y: np.ndarray, x_test: np.ndarray, seed: int = 0,
                    epochs: int = MLP_EPOCHS) -> np.ndarray:
    """A small MLP fitted (squared error, Adam, batches of 256) on standardised ``x`` -> ``y``; its predictions
    for ``x_test``. Seeded: the same call gives the same numbers."""
    import torch
    from torch import nn

    gen = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-6
    xt = torch.as_tensor((x - mean) / scale, dtype=torch.float32)
    yt = torch.as_tensor(y, dtype=torch.float32)
    net = nn.Sequential(nn.Linear(x.shape[1], MLP_HIDDEN), nn.ELU(), nn.Linear(MLP_HIDDEN, MLP_HIDDEN), nn.ELU(),
                        nn.Linear(MLP_HIDDEN, y.shape[1]))
    opt = torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=1e-4)
    for _ in range(epochs):
        order = torch.randperm(len(xt), generator=gen)
        for i in range(0, len(xt), 256):
            b = order[i:i + 256]
            loss = (net(xt[b]) - yt[b]).pow(2).sum(dim=1).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    with torch.no_grad():
        return net(torch.as_tensor((x_test - mean) / scale, dtype=torch.float32)).numpy().astype(float)


def member_probe(feat_train: np.ndarray, members_train: np.ndarray, feat_test: np.ndarray,
                 members_test: np.ndarray, ridge: float = 1e-2, reader: str = "linear") -> dict[str, float]:
    """Median / 90th-percentile error (m) of per-slot maps (``reader``: linear or mlp) features -> visible
    member positions. ``members_*`` (N, M, 2): robot-frame positions of the members in view, NaN otherwise."""
    return _slot_probe(lambda m: feat_train, members_train, lambda m: feat_test, members_test, _reader(reader, ridge))


def pixel_probe(px_train: np.ndarray, members_train: np.ndarray, px_test: np.ndarray, members_test: np.ndarray,
                ridge: float = 1e-2, reader: str = "linear") -> dict[str, float]:
    """``member_probe``'s reference: each member slot's position from its own true pixel (``px_*`` (N, M, 2))."""
    return _slot_probe(lambda m: px_train[:, m], members_train, lambda m: px_test[:, m], members_test,
                       _reader(reader, ridge))


def _reader(name: str, ridge: float) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    if name == "linear":
        return lambda x, y, x_test: predict_linear(fit_linear(x, y, ridge), x_test)
    if name == "mlp":
        return fit_predict_mlp
    raise ValueError(f"probe reader {name!r}: expected one of {READERS}")


def _slot_probe(train_x, members_train: np.ndarray, test_x, members_test: np.ndarray,
                fit_predict: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> dict[str, float]:
    errors = []
    for m in range(members_train.shape[1]):
        tr, te = np.isfinite(members_train[:, m, 0]), np.isfinite(members_test[:, m, 0])
        x_tr = train_x(m)
        if tr.sum() < x_tr.shape[1] + 2 or not te.any():
            continue
        errors.append(fit_predict(x_tr[tr], members_train[tr, m], test_x(m)[te]) - members_test[te, m])
    e = np.concatenate(errors) if errors else np.zeros((0, 2))
    dist = np.linalg.norm(e, axis=1)

    def med(v: np.ndarray) -> float:
        return float(np.median(v)) if len(v) else float("nan")

    return {"median_m": med(dist), "p90_m": float(np.percentile(dist, 90)) if len(dist) else float("nan"),
            "median_depth_m": med(np.abs(e[:, 0])), "median_lateral_m": med(np.abs(e[:, 1])),
            "scored": int(len(dist))}


def visible_members(data: dict[str, np.ndarray]) -> np.ndarray:
    """Members' robot-frame positions where their torso is in the image, NaN elsewhere (frames file arrays)."""
    out = data["members_rel"].astype(float).copy()
    out[~np.isfinite(data["members_px"][..., 0])] = np.nan
    return out
