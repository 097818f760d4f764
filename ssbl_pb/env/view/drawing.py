"""Overlays on top-down frames: zones, o-space, free slot, paths (OpenCV, RGB images)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.task import TaskParams
from ...params import SocialParams
from .cameras import TopDown

ROBOT_COLOUR = (40, 40, 40)
SLOT_COLOUR = (220, 30, 30)
PATH_COLOUR = (200, 40, 160)


def _pt(cam: TopDown, xy: np.ndarray) -> tuple[int, int]:
    u, v = cam.to_pixel(xy)
    return int(round(u)), int(round(v))


def draw_overlay(img: np.ndarray, cam: TopDown, trajectory: list[dict[str, Any]], social: SocialParams,
                 task: TaskParams) -> np.ndarray:
    """Draw intimate/personal zones, the o-space circle, the free slot and the robot's path so far."""
    import cv2  # heavy: OpenCV (~0.2 s), only for rendering

    out = np.ascontiguousarray(img.copy())
    ppm = cam.pixels_per_metre
    now = trajectory[-1]
    for m in now["members"]:
        c = _pt(cam, m)
        cv2.circle(out, c, int((social.human_radius + task.personal_zone) * ppm), (230, 170, 40), 1, cv2.LINE_AA)
        cv2.circle(out, c, int((social.human_radius + task.intimate_zone) * ppm), (220, 60, 40), 1, cv2.LINE_AA)
    cv2.circle(out, _pt(cam, now["centre"]), int(now["radius"] * ppm), (90, 150, 90), 1, cv2.LINE_AA)
    s = _pt(cam, now["slot"])
    cv2.drawMarker(out, s, SLOT_COLOUR, cv2.MARKER_TILTED_CROSS, max(6, int(0.3 * ppm)), 2)
    pts = np.array([_pt(cam, st["robot"][:2]) for st in trajectory], dtype=np.int32)
    if len(pts) > 1:
        cv2.polylines(out, [pts], False, PATH_COLOUR, 2, cv2.LINE_AA)
    cv2.putText(out, f"t={now['t']:.1f}s", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
    return out
