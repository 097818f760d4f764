"""Policies shipped with the package (data only): ``vector/`` holds the trained Vector model."""

from pathlib import Path

SHIPPED_DIR = Path(__file__).resolve().parent
SHIPPED = {"vector": SHIPPED_DIR / "vector"}
