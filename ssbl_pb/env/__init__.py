"""Simulation: formulas (forces, reward, shield, ...), rooms, engine (N copies), view (PyBullet), gymenv (Gymnasium)."""

from .compile_cache import use_source_keyed_cache

use_source_keyed_cache()
