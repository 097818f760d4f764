"""Policies shipped with the package (data only): ``vector/`` holds the trained Vector model,
``camera_speed_saev/`` the CameraSpeed policy with its frozen SAEV encoder (``encoder.pt``)."""

from pathlib import Path

SHIPPED_DIR = Path(__file__).resolve().parent
SHIPPED = {"vector": SHIPPED_DIR / "vector", "camera_speed_saev": SHIPPED_DIR / "camera_speed_saev"}
SHIPPED_ENCODERS = {"saev": SHIPPED_DIR / "camera_speed_saev" / "encoder.pt"}  # config encoder_checkpoint default
