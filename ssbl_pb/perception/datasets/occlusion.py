"""The "feet hidden" benchmark: real frames with every ground-truth person's lower body painted over with the
video's median background, as a camera at joining distance sees people (Pepper's CameraTop, 1.15 m up with a
44 deg vertical field of view, loses the floor nearer than about 2.8 m: feet and often knees are below the
image). Each GT box is painted from ``keep`` (0.55) of its height down to its bottom edge, across its width.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from ..tracking.pipeline import open_video, read_frames

KEEP = 0.55  # share of each GT box (from its top) left visible


def median_background(video: str | Path, samples: int = 60) -> np.ndarray:
    """Per-pixel median of ``samples`` frames spread evenly over the whole video (walkers move on, the static
    scene stays): the background painted over lower bodies."""
    cap, n, _, _ = open_video(video)
    cap.release()
    if samples < 1:
        raise UserError(f"samples = {samples!r}: expected >= 1")
    step = max(1, n // samples)
    frames = [f for i, f in read_frames(video) if i % step == 0]
    return np.median(np.stack(frames), axis=0).astype(np.uint8)


def hide_lower_bodies(frame: np.ndarray, boxes: np.ndarray, background: np.ndarray,
                      keep: float = KEEP) -> np.ndarray:
    """A copy of ``frame`` with each box ``x, y, w, h`` (n, >=4) painted from ``keep`` of its height down
    with ``background`` (same shape as ``frame``)."""
    if frame.shape != background.shape:
        raise UserError(f"background {background.shape} does not match the frame {frame.shape}")
    if not 0 <= keep <= 1:
        raise UserError(f"keep = {keep!r}: expected in [0, 1]")
    out = frame.copy()
    h, w = frame.shape[:2]
    for x, y, bw, bh in np.asarray(boxes, dtype=float).reshape(-1, np.shape(boxes)[-1] if len(boxes) else 4)[:, :4]:
        x0, x1 = int(np.clip(np.floor(x), 0, w)), int(np.clip(np.ceil(x + bw), 0, w))
        y0, y1 = int(np.clip(np.floor(y + keep * bh), 0, h)), int(np.clip(np.ceil(y + bh), 0, h))
        out[y0:y1, x0:x1] = background[y0:y1, x0:x1]
    return out


class FeetHidden:
    """``painter(index, frame)`` -> the frame with that frame's GT people's lower bodies painted over.

    ``gt``: rows ``frame (0-based), id, left, top, w, h`` (``pets.load_ground_truth``)."""

    def __init__(self, gt: np.ndarray, background: np.ndarray, keep: float = KEEP) -> None:
        self.background, self.keep = background, keep
        gt = np.asarray(gt, dtype=float)
        self.by_frame = {int(f): gt[gt[:, 0] == f, 2:6] for f in np.unique(gt[:, 0])}

    def __call__(self, index: int, frame: np.ndarray) -> np.ndarray:
        boxes = self.by_frame.get(int(index), np.zeros((0, 4)))
        return hide_lower_bodies(frame, boxes, self.background, self.keep)
