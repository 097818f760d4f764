"""Simulation: PyBullet world, social force field model, rewards, the Gymnasium env and baselines."""

from .compile_cache import use_source_keyed_cache

use_source_keyed_cache()
