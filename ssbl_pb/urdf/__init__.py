"""Pepper and human-proxy URDFs shipped with the package."""

from __future__ import annotations

from pathlib import Path

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
