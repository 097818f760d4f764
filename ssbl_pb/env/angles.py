"""Angle wrapping for arrays (the batched env's counterpart of ``math.remainder(x, 2 pi)``)."""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap(x: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped to [-pi, pi] elementwise, as ``math.remainder(x, 2 pi)`` does for one number."""
    return x - np.rint(x * (1.0 / TWO_PI)) * TWO_PI
