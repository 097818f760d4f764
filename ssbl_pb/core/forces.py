"""Social force field model (SFFM), paper section III-C, eqs. 8-10: each force on one agent, compiled.

Agents live in one array ``P`` (k, 2) (metres, world frame). ``mask[a, b]`` says whether agent ``b`` may count as
a neighbour of agent ``a``; the zone radius then decides who actually does. ``repulsion_on``, ``equality_on`` and
``cohesion_on`` give the force (and orientation) on agent ``a``: the members' motion (``humans.group_step``), the
robot's field in the rewards and the SFFM baseline all call these. Degenerate cases return zeros, never NaN: an
agent with nobody in a zone feels no force from it, and coincident agents (no defined direction) exert none.
``normalize`` and ``soft_normalize`` are the model's normalisations for arrays (the SFFM baseline).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

EPS = 1e-9


@njit(cache=True)
def repulsion_on(a: int, P: np.ndarray, zones: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """Eq. 8: ``F_r = -(d_p - d_min)^2 p_r/|p_r|``, ``p_r = sum_i (p_i - p)`` over agents inside the zone.

    ``zones[a, b]`` is the personal zone agent ``a`` keeps from agent ``b`` (eq. 8's ``d_p``); the magnitude is
    the deepest intrusion, ``max_b (d_p[a, b] - d_ab)^2`` (eq. 8 itself for a single radius). Zero when nobody
    is inside."""
    cnt, sx, sy, depth = 0.0, 0.0, 0.0, 0.0
    for b in range(P.shape[0]):
        if b == a or not mask[a, b]:
            continue
        dist = math.hypot(P[b, 0] - P[a, 0], P[b, 1] - P[a, 1])
        if dist < zones[a, b]:
            cnt += 1.0
            sx += P[b, 0]
            sy += P[b, 1]
            depth = max(depth, zones[a, b] - dist)
    prx, pry = sx - cnt * P[a, 0], sy - cnt * P[a, 1]
    nr = math.hypot(prx, pry)
    if nr <= EPS:
        return 0.0, 0.0
    return -(depth * depth) * prx / nr, -(depth * depth) * pry / nr


@njit(cache=True)
def equality_on(a: int, P: np.ndarray, d_s: float, mask: np.ndarray) -> tuple[float, float, float, float]:
    """Eq. 9: ``F_e = (1 - m/|c - p|)(c - p)`` and the orientation ``d_e = sum_i (p_i - p)``.

    ``c = (p + sum_i p_i)/(N_s + 1)`` over the agents inside the social zone ``d_s``; ``m`` is the mean distance
    of those agents (``a`` included) from ``c``. Returns (F_e x, F_e y, d_e x, d_e y)."""
    cnt, sx, sy = 0.0, 0.0, 0.0
    for b in range(P.shape[0]):
        if b != a and mask[a, b] and math.hypot(P[b, 0] - P[a, 0], P[b, 1] - P[a, 1]) < d_s:
            cnt += 1.0
            sx += P[b, 0]
            sy += P[b, 1]
    c1 = cnt + 1.0
    cx, cy = (P[a, 0] + sx) / c1, (P[a, 1] + sy) / c1
    own = math.hypot(cx - P[a, 0], cy - P[a, 1])
    total = own
    for b in range(P.shape[0]):
        if b != a and mask[a, b] and math.hypot(P[b, 0] - P[a, 0], P[b, 1] - P[a, 1]) < d_s:
            total += math.hypot(cx - P[b, 0], cy - P[b, 1])
    dx, dy = sx - cnt * P[a, 0], sy - cnt * P[a, 1]
    if own <= EPS:
        return 0.0, 0.0, dx, dy
    scale = 1.0 - (total / c1) / own
    return scale * (cx - P[a, 0]), scale * (cy - P[a, 1]), dx, dy


@njit(cache=True)
def cohesion_on(a: int, P: np.ndarray, ox: float, oy: float, s: float, d_s: float, d_pub: float,
                mask: np.ndarray) -> tuple[float, float, float, float]:
    """Eq. 10: ``F_c = alpha (1 - s/|o - p|)(o - p)``, ``alpha = N_a/(N_s + 1)``, ``d_c = sum_i (p_i - p)``.

    ``o`` is the conversation centre, ``s`` the o-space radius agent ``a`` keeps from it; ``N_a`` counts the
    agents inside the public zone ``d_pub`` and ``N_s`` those inside the social zone ``d_s``. An agent exactly at
    ``o`` has no defined direction and feels no cohesion. Returns (F_c x, F_c y, d_c x, d_c y)."""
    n_a, n_s, sx, sy = 0.0, 0.0, 0.0, 0.0
    for b in range(P.shape[0]):
        if b == a or not mask[a, b]:
            continue
        dist = math.hypot(P[b, 0] - P[a, 0], P[b, 1] - P[a, 1])
        if dist < d_pub:
            n_a += 1.0
            sx += P[b, 0]
            sy += P[b, 1]
        if dist < d_s:
            n_s += 1.0
    dx, dy = sx - n_a * P[a, 0], sy - n_a * P[a, 1]
    tx, ty = ox - P[a, 0], oy - P[a, 1]
    d = math.hypot(tx, ty)
    if d <= EPS:
        return 0.0, 0.0, dx, dy
    scale = (n_a / (n_s + 1.0)) * (1.0 - s / d)
    return scale * tx, scale * ty, dx, dy


def normalize(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors and norms of ``v`` (..., 2); a zero vector maps to zero (safe at zero length)."""
    n = np.hypot(v[..., 0], v[..., 1])
    ok = n > EPS
    return v * (ok / np.where(ok, n, 1.0))[..., None], n


def soft_normalize(v: np.ndarray, scale: float) -> np.ndarray:
    """``v / max(|v|, scale)``: a unit vector far from zero, linear (``v/scale``) within ``scale`` of it."""
    return v / np.maximum(np.hypot(v[..., 0], v[..., 1]), scale)[..., None]
