"""Social force field model (SFFM), paper section III-C, eqs. 8-10, as pure vectorised numpy functions.

All agents live in one array ``P`` of shape (k, 2) (metres, world frame). ``mask[i, j]`` says whether agent
``j`` may count as a neighbour of agent ``i`` (default: every other agent); the zone radius then decides who
actually does. Each force returns an array (k, 2); orientations likewise. Every function also takes a batch
of independent scenes, ``P`` (..., k, 2) and ``mask`` (..., k, k), and answers per scene (groups of different
sizes: pad ``P`` and mask the padding out), so many envs can share one call. Degenerate cases return zeros, never
NaN: an agent with nobody in a zone feels no force from it, and coincident agents (zero separation, so no
defined direction) exert none. ``pair`` lets a caller that evaluates several forces share one
``pairwise(P)``; it never changes a result.
"""

from __future__ import annotations

import functools

import numpy as np

_EPS = 1e-9
Pair = tuple[np.ndarray, np.ndarray]


def normalize(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors and norms of ``v`` (..., 2); a zero vector maps to zero (safe at zero length)."""
    n = np.hypot(v[..., 0], v[..., 1])
    ok = n > _EPS
    return v * (ok / np.where(ok, n, 1.0))[..., None], n


def soft_normalize(v: np.ndarray, scale: float) -> np.ndarray:
    """``v / max(|v|, scale)``: a unit vector far from zero, linear (``v/scale``) within ``scale`` of it."""
    return v / np.maximum(np.hypot(v[..., 0], v[..., 1]), scale)[..., None]


def pairwise(P: np.ndarray) -> Pair:
    """``diff[i, j] = p_j - p_i`` (k, k, 2) and ``dist[i, j]`` (k, k) (with P's leading batch axes, if any)."""
    diff = P[..., None, :, :] - P[..., :, None, :]
    return diff, np.hypot(diff[..., 0], diff[..., 1])


@functools.lru_cache(maxsize=16)
def _off_diagonal(k: int) -> np.ndarray:
    return ~np.eye(k, dtype=bool)


def _neighbours(dist: np.ndarray, radius: float | np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    inside = (dist < radius) & _off_diagonal(dist.shape[-1])
    return inside if mask is None else inside & mask


def _sum_toward(W: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``sum_j W[i, j] (p_j - p_i)`` for each i."""
    return W @ P - W.sum(axis=-1)[..., None] * P


def repulsion(P: np.ndarray, d_p: float | np.ndarray, mask: np.ndarray | None = None,
              pair: Pair | None = None) -> np.ndarray:
    """Eq. 8: ``F_r = -(d_p - d_min)^2 p_r/|p_r|``, ``p_r = sum_i (p_i - p)`` over agents inside ``d_p``.

    ``d_min`` is the distance to the closest such agent. Zero when nobody is inside the personal zone. ``d_p``
    may also be a (k, k) array, ``d_p[i, j]`` the zone agent ``i`` keeps from agent ``j``; the magnitude is then
    the deepest intrusion, ``max_j (d_p[i, j] - d_ij)^2`` (the same as eq. 8 for a single radius).
    """
    _, dist = pair if pair is not None else pairwise(P)
    inside = _neighbours(dist, d_p, mask)
    if not inside.any():
        return np.zeros_like(P)
    p_r = _sum_toward(inside.astype(P.dtype), P)
    depth = np.where(inside, d_p - dist, 0.0).max(axis=-1)
    unit, _ = normalize(p_r)
    return -(depth ** 2)[..., None] * unit


def equality(P: np.ndarray, d_s: float, mask: np.ndarray | None = None,
             pair: Pair | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 9: ``F_e = (1 - m/|c - p|)(c - p)`` and orientation ``d_e = sum_i (p_i - p)``.

    ``c = (p + sum_i p_i)/(N_s + 1)`` over the agents inside the social zone ``d_s``; ``m`` is the mean distance
    of those members (the agent included) from ``c``.
    """
    _, dist = pair if pair is not None else pairwise(P)
    W = _neighbours(dist, d_s, mask).astype(P.dtype)
    WP, count = W @ P, W.sum(axis=-1)
    count1 = (count + 1.0)[..., None]
    c = (P + WP) / count1
    to_c = c[..., :, None, :] - P[..., None, :, :]  # [i, j] = c_i - p_j
    d_to_c = np.hypot(to_c[..., 0], to_c[..., 1])
    self_d = np.diagonal(d_to_c, axis1=-2, axis2=-1)
    m = (self_d + (W * d_to_c).sum(axis=-1)) / count1[..., 0]
    ok = self_d > _EPS
    scale = np.where(ok, 1.0 - m / np.where(ok, self_d, 1.0), 0.0)
    return scale[..., None] * (c - P), WP - count[..., None] * P


def cohesion(P: np.ndarray, o: np.ndarray, s: float, d_s: float, d_pub: float, mask: np.ndarray | None = None,
             pair: Pair | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 10: ``F_c = alpha (1 - s/|o - p|)(o - p)``, ``alpha = N_a/(N_s + 1)``, ``d_c = sum_i (p_i - p)``.

    ``o`` is the conversation centre (2,) or one per agent (k, 2), ``s`` the o-space radius; ``N_a`` counts the
    agents inside the public zone ``d_pub`` and ``N_s`` those inside the social zone ``d_s``. An agent exactly
    at ``o`` has no defined direction and feels no cohesion. Batched: ``o`` (..., 1, 2) and ``s`` (..., 1) give
    each scene its own centre and radius.
    """
    _, dist = pair if pair is not None else pairwise(P)
    A = _neighbours(dist, d_pub, mask).astype(P.dtype)
    n_a = A.sum(axis=-1)
    alpha = n_a / (_neighbours(dist, d_s, mask).sum(axis=-1) + 1.0)
    op = o - P
    d = np.hypot(op[..., 0], op[..., 1])
    ok = d > _EPS
    scale = np.where(ok, alpha * (1.0 - s / np.where(ok, d, 1.0)), 0.0)
    return scale[..., None] * op, A @ P - n_a[..., None] * P
