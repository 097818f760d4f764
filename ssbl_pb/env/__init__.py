"""Simulation: rooms, engine (N copies), view (PyBullet), gymenv (Gymnasium); its formulas are in ``core``."""
