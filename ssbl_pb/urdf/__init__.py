"""Pepper and human-proxy URDFs shipped with the package."""

from __future__ import annotations

from pathlib import Path

URDF_DIR = Path(__file__).resolve().parent


def urdf_path(name: str) -> Path:
    """Path of a shipped URDF, ``name`` in {"pepper", "human"}; raises FileNotFoundError naming the file."""
    path = URDF_DIR / f"{name}.urdf"
    if not path.is_file():
        raise FileNotFoundError(f"URDF '{name}' not found: expected {path}")
    return path
