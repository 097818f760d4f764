"""Videos and contact sheets: top-down episode videos with zones drawn, first-person frame sheets."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from ..agents.policies import Policy
from ..agents.rollout import run_episode
from ..errors import UserError


class VideoError(UserError):
    """A video cannot be written; the message names the file."""


def write_mp4(path: Path, frames: list[np.ndarray], fps: int = 10) -> None:
    """RGB frames to an mp4 (OpenCV ``mp4v``), written to a temporary name and moved in place."""
    if not frames:
        raise VideoError(f"{path}: no frames to write")
    h, w = frames[0].shape[:2]
    tmp = Path(path).with_name(f".{Path(path).name}.tmp.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    if not writer.isOpened():
        raise VideoError(f"{path}: OpenCV cannot open an mp4v writer here")
    try:
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    finally:
        writer.release()
    os.replace(tmp, path)


def contact_sheet(frames: list[np.ndarray], cols: int = 6, scale: int = 2, labels: list[str] | None = None
                  ) -> np.ndarray:
    """Frames tiled into one RGB image (nearest-neighbour upscaled by ``scale``)."""
    tiles = [cv2.resize(f, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST) for f in frames]
    h, w = tiles[0].shape[:2]
    rows = (len(tiles) + cols - 1) // cols
    sheet = np.full((rows * (h + 4), cols * (w + 4), 3), 255, dtype=np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, cols)
        sheet[r * (h + 4):r * (h + 4) + h, c * (w + 4):c * (w + 4) + w] = t
        if labels:
            cv2.putText(sheet, labels[i], (c * (w + 4) + 3, r * (h + 4) + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (255, 255, 255), 1, cv2.LINE_AA)
    return sheet


def record_episode(env, policy: Policy, seed: int, first_person: int = 0, fp_size: int = 84
                   ) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    """Run one episode; top-down frames (``env.render()``) and every ``first_person``-th first-person frame."""
    top, fp = [], []
    counter = [0]

    def grab(e) -> None:
        top.append(e.render())
        if first_person and counter[0] % first_person == 0:
            fp.append(e.unwrapped.world.render_first_person(fp_size, fp_size)[0])
        counter[0] += 1

    res = run_episode(env, policy, seed, keep_trajectory=False, on_step=grab)
    return top, fp, res.metrics


def save_png(path: Path, rgb: np.ndarray) -> None:
    tmp = Path(path).with_name(f".{Path(path).name}.tmp.png")
    if not cv2.imwrite(str(tmp), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
        raise VideoError(f"{path}: cannot write the image")
    os.replace(tmp, path)
