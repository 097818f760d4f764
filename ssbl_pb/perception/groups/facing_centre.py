"""The conversation centre from where the members face: where their facing rays meet (``facing_centre``), and the
same robust to a facing far off (``robust_facing_centre``, MoveNet's chain). ``estimate.GroupModel`` uses them."""

from __future__ import annotations

import math

import numpy as np

FACING_MIN_SPREAD = 0.35  # rad: facing rays meeting at less than this do not fix a point by their crossing
FACING_MAX_REACH = 2.5  # m: a centre farther than this from every member, or behind them, is not their o-space
FACING_AGREE = math.radians(60)  # rad: members all facing within this of their mean direction face one way


def facing_centre(members: np.ndarray, facing: np.ndarray, std: np.ndarray, reach: float) -> np.ndarray | None:
    """The o-space centre from the members' facing (Kendon: each member's transactional segment points at the
    o-space), or None when fewer than two facings are known or they do not point at one place.

    Rays that cross (at ``FACING_MIN_SPREAD`` or more) give their crossing, by weighted least squares over the
    rays' normal distances (weights 1 / std^2), if it lies ahead of every member within ``FACING_MAX_REACH``.
    Rays that face one way, nearly parallel (people side by side, or seen from behind, where the facing is coarse),
    give the point ``h`` ahead of the members' centroid along their mean facing, ``h`` the crossing distance of
    rays converging by the angle between them, at most ``reach`` (the model's o-space radius). Rays facing each
    other (vis-a-vis) give None: the positions tell the centre then (``group_circle``). ``facing`` NaN: unknown."""
    pts = np.asarray(members, dtype=float).reshape(-1, 2)
    f, sd = np.asarray(facing, dtype=float).ravel(), np.asarray(std, dtype=float).ravel()
    known = np.isfinite(f) & np.isfinite(sd) & (sd > 0)
    if known.sum() < 2:
        return None
    pts, f, w = pts[known], f[known], 1.0 / sd[known] ** 2
    u = np.column_stack([np.cos(f), np.sin(f)])
    proj = np.eye(2)[None] - u[:, :, None] * u[:, None, :]  # onto each ray's normal
    a = (w[:, None, None] * proj).sum(axis=0)
    if np.linalg.eigvalsh(a)[0] >= math.sin(FACING_MIN_SPREAD) ** 2 * w.min():
        b = (w[:, None, None] * proj @ pts[:, :, None]).sum(axis=0).ravel()
        c = np.linalg.solve(a, b)
        ahead = ((c - pts) * u).sum(axis=1)
        if (ahead > 0).all() and np.hypot(*(c - pts).T).min() <= FACING_MAX_REACH:
            return c
        return None
    mean = (w[:, None] * u).sum(axis=0)
    if np.hypot(*mean) < 1e-9:
        return None
    mean = mean / np.hypot(*mean)
    if (u @ mean < math.cos(FACING_AGREE)).any():  # not one way: facing each other
        return None
    spread = float(np.arccos(np.clip(u @ mean, -1.0, 1.0)).max())  # half the angle between the outermost rays
    half_width = 0.5 * float(np.ptp((pts - pts.mean(axis=0)) @ np.array([-mean[1], mean[0]])))
    h = min(half_width / math.tan(spread), reach) if spread > 1e-6 else reach
    return pts.mean(axis=0) + h * mean


FACING_OUTLIER = math.radians(45)  # rad: a ray missing the estimate by more is an outlier (a facing turned back)
OUTLIER_WEIGHT = 0.02  # an outlier ray's share of its weight: kept, so an estimate can come back to it
CENTROID_STD_M = 0.2  # m: how far a conversation's centre lies from its members' centroid (calibrated groups:
#   0.09-0.27 m at the median per formation, ``calib.groups`` on shared/data/fformations)
RAY_MIN_M, RAY_MIN_STD = 0.3, 0.05  # m, rad: floors of a ray's length and facing error in its weight


def robust_facing_centre(members: np.ndarray, facing: np.ndarray, std: np.ndarray, iterations: int = 20
                         ) -> np.ndarray | None:
    """The o-space centre of three or more members from their facing rays and their centroid together, robust to
    a facing that is wrong (MoveNet's keypoints turn a person seen from the side or behind by up to 180 deg).

    Iteratively reweighted least squares over each ray's normal distance (its std the ray's length times its
    facing std, floored at ``RAY_MIN_M`` and ``RAY_MIN_STD``) and the distance to the members' centroid (std
    ``CENTROID_STD_M``: the calibrated model's centre is the centroid, ``group_circle``); a ray that misses the
    estimate by more than ``FACING_OUTLIER`` keeps ``OUTLIER_WEIGHT`` of its weight. None for fewer than three
    members or two known facings (``group_circle`` then)."""
    pts = np.asarray(members, dtype=float).reshape(-1, 2)
    f, sd = np.asarray(facing, dtype=float).ravel(), np.asarray(std, dtype=float).ravel()
    known = np.isfinite(f) & np.isfinite(sd) & (sd > 0)
    if len(pts) < 3 or known.sum() < 2:
        return None
    centroid = pts.mean(axis=0)
    p, sd = pts[known], np.maximum(sd[known], RAY_MIN_STD)
    u = np.column_stack([np.cos(f[known]), np.sin(f[known])])
    proj = np.eye(2)[None] - u[:, :, None] * u[:, None, :]  # onto each ray's normal
    prior = 1.0 / CENTROID_STD_M ** 2
    c = centroid
    for _ in range(iterations):
        to_c = c - p
        d = np.hypot(*to_c.T)
        w = 1.0 / (np.maximum(d, RAY_MIN_M) * sd) ** 2
        cos_miss = (to_c * u).sum(axis=1) / np.maximum(d, 1e-9)
        w = np.where(cos_miss < math.cos(FACING_OUTLIER), OUTLIER_WEIGHT * w, w)
        a = (w[:, None, None] * proj).sum(axis=0) + prior * np.eye(2)
        b = (w[:, None, None] * proj @ p[:, :, None]).sum(axis=0).ravel() + prior * centroid
        c, last = np.linalg.solve(a, b), c
        if np.hypot(*(c - last)) < 1e-6:
            break
    return c
