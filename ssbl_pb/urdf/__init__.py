"""Pepper, the human proxy and the person bodies (``bodies/``, made by ``tools/make_bodies.py``) shipped with the
package."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

URDF_DIR = Path(__file__).resolve().parent
# the proxies' RGBA colours by member index (``human.urdf`` is drawn in them): the colour detector looks for these
HUMAN_COLOURS = [(0.20, 0.70, 0.30, 1), (0.20, 0.40, 0.85, 1), (0.90, 0.50, 0.10, 1), (0.60, 0.30, 0.75, 1),
                 (0.85, 0.20, 0.25, 1)]


def urdf_path(name: str) -> Path:
    """Path of a shipped URDF, ``name`` in {"pepper", "human"}; raises FileNotFoundError naming the file."""
    path = URDF_DIR / f"{name}.urdf"
    if not path.is_file():
        raise FileNotFoundError(f"URDF '{name}' not found: expected {path}")
    return path


BODY_DIR = URDF_DIR / "bodies"


@functools.cache
def body_manifest() -> tuple[dict[str, Any], ...]:
    """The shipped bodies (``bodies/bodies.json``): each one's ``urdf``, ``height`` (m), ``sex``, ``build``,
    ``pose``, part ``colours`` (RGB 0-1) and ``triangles``; raises FileNotFoundError naming the file."""
    path = BODY_DIR / "bodies.json"
    if not path.is_file():
        raise FileNotFoundError(f"body manifest not found: expected {path} (made by tools/make_bodies.py)")
    return tuple(json.loads(path.read_text())["bodies"])


def body_path(index: int) -> Path:
    """URDF of body ``index`` (0 .. len(body_manifest()) - 1)."""
    bodies = body_manifest()
    if not 0 <= index < len(bodies):
        raise IndexError(f"body {index}: expected 0..{len(bodies) - 1}")
    return BODY_DIR / bodies[index]["urdf"]
