"""PyBullet, imported in one place without the "pybullet build time" line its C module prints on stderr."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from types import ModuleType


def _import_quietly() -> ModuleType:
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no usable stderr (a closed descriptor): nothing to protect
        import pybullet

        return pybullet
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            import pybullet

            with contextlib.suppress(Exception):  # C stdio buffers the banner when stderr is not a terminal
                ctypes.CDLL(None).fflush(None)
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


pybullet = _import_quietly()
