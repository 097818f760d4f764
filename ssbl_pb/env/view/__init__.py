"""The PyBullet view of the state: the scene (world), cameras, overlays (drawing), pybullet."""
