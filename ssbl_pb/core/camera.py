"""Camera projection as OpenGL matrices (PyBullet's 16-float column-major lists): the pinhole intrinsics a calibrated
camera gives, in the form TinyRenderer takes, so that a world point lands on the OpenCV pixel."""

from __future__ import annotations

import numpy as np

NEAR, FAR = 0.05, 40.0


def gl_matrix(m: np.ndarray) -> list[float]:
    """A 4x4 numpy matrix as PyBullet's 16-float column-major list."""
    return [float(x) for x in np.asarray(m, dtype=float).flatten(order="F")]


def projection_from_intrinsics(fx: float, fy: float, cx: float, cy: float, width: int, height: int,
                               near: float = NEAR, far: float = FAR) -> list[float]:
    """OpenGL projection equivalent to a pinhole camera (OpenCV: pixel centres at integer coords, y down).

    Offsets are for PyBullet's TinyRenderer, measured (tests/test_calib_camera.py): it samples column ``i``
    at window x = ``i`` (not ``i + 0.5``) and flips rows as ``H - 1 - row``, so the textbook ``cx + 0.5``
    and ``cy + 0.5`` become ``cx`` and ``cy + 1``; a world point then lands on the OpenCV pixel.
    """
    m = np.zeros((4, 4))
    m[0, 0] = 2.0 * fx / width
    m[1, 1] = 2.0 * fy / height
    m[0, 2] = 1.0 - 2.0 * cx / width
    m[1, 2] = 2.0 * (cy + 1.0) / height - 1.0
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2.0 * far * near / (far - near)
    m[3, 2] = -1.0
    return gl_matrix(m)
