"""Policies shipped with the package (data only): ``vector/`` holds the trained Vector model,
``camera_speed_saev/`` the CameraSpeed policy with its frozen SAEV encoder (``encoder.pt``)."""

from pathlib import Path

SHIPPED_DIR = Path(__file__).resolve().parent
# the two the project ships, and any other that tools/ship_policy.py --name NAME put here
SHIPPED = {"vector": SHIPPED_DIR / "vector", "camera_speed_saev": SHIPPED_DIR / "camera_speed_saev"} | {
    p.name: p for p in sorted(SHIPPED_DIR.iterdir()) if p.name.isidentifier() and (p / "model.zip").is_file()}
SHIPPED_ENCODERS = {"saev": SHIPPED_DIR / "camera_speed_saev" / "encoder.pt"}  # config encoder_checkpoint default
