"""Simulation: PyBullet world, social force field model, rewards, the Gymnasium env and baselines."""
