"""How many ground-truth people a person detector's boxes cover, frame by frame, before any tracking
(``tools/detector_coverage.py``; docs/tracking.md): with the feet in view, and with each person's lower body painted
over with the video's median background, as a robot at joining distance sees people."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ..cli import progress
from ..perception.datasets.occlusion import KEEP, FeetHidden, median_background
from ..perception.datasets.pets import load_ground_truth
from ..perception.detection.learned import SsdDetector, box_iou
from ..perception.detection.movenet import MoveNetDetector
from ..perception.tracking.pipeline import read_frames
from ..perception.tracking.tuning import PipelineParams

DETECTORS = ("ssd", "movenet")  # HOG needs every frame in order (its background model learns): not here


def make(name: str) -> Any:
    """The detector ``name`` with its built-in settings (the SSD as tuned in ``PipelineParams``)."""
    return SsdDetector(PipelineParams().ssd) if name == "ssd" else MoveNetDetector()


def coverage(detect: Any, video: Path, gt: np.ndarray, frames: range, paint: Any | None) -> dict[str, float]:
    """For one detector over ``frames``: GT person-frames, boxes, the share of people whose visible box (the upper
    body) a box overlaps with IoU >= 0.5, whose whole box one does, whose upper or whole box one overlaps with
    IoU >= 0.3, and the median detector time (ms). ``paint(i, frame)``: the feet-hidden frame, or None."""
    people = boxes = upper = whole = either = 0
    ms = []
    wanted = set(frames)
    for i, frame in progress(read_frames(str(video), frames.start, frames.stop), "frames", "frame",
                             total=frames.stop - frames.start):
        if i not in wanted:
            continue
        f = paint(i, frame) if paint is not None else frame
        t = time.perf_counter()
        b = np.asarray(detect(f), dtype=float).reshape(-1, 5)
        ms.append(1e3 * (time.perf_counter() - t))
        g = gt[gt[:, 0] == i, 2:6]
        boxes += len(b)
        people += len(g)
        if not len(g) or not len(b):
            continue
        up = g.copy()
        up[:, 3] *= KEEP
        iu, iw = box_iou(up, b).max(axis=1), box_iou(g, b).max(axis=1)
        upper += int((iu >= 0.5).sum())
        whole += int((iw >= 0.5).sum())
        either += int((np.maximum(iu, iw) >= 0.3).sum())
    n = max(people, 1)
    return {"person_frames": people, "boxes": boxes, "upper_iou50": upper / n, "whole_iou50": whole / n,
            "either_iou30": either / n, "ms_median": float(np.median(ms)) if ms else float("nan")}


def measure(detectors: list[str], video: Path, gt_path: Path, frames: range, hide_feet: bool
            ) -> dict[str, dict[str, dict[str, float]]]:
    """detector -> case ("visible", "feet hidden") -> ``coverage``."""
    gt = load_ground_truth(gt_path)
    paint = FeetHidden(gt, median_background(str(video))) if hide_feet else None
    rows: dict[str, dict[str, dict[str, float]]] = {}
    for name in detectors:
        detect = make(name)
        rows[name] = {"visible": coverage(detect, video, gt, frames, None)}
        if paint is not None:
            rows[name]["feet hidden"] = coverage(detect, video, gt, frames, paint)
    return rows


def markdown(rows: dict[str, dict[str, dict[str, float]]], video: Path, frames: range, command: str) -> str:
    """The table for docs/tracking.md, its command above it."""
    lines = [f"Detector coverage on {video.name} frames {frames.start}-{frames.stop - 1}, every {frames.step}th "
             f"(`{command}`): the share of GT people a box covers, before tracking.", "",
             "| detector | frames | people | boxes | upper body IoU>=0.5 | whole IoU>=0.5 | either IoU>=0.3 | ms |",
             "|---|---|---|---|---|---|---|---|"]
    for name, by in rows.items():
        for case, r in by.items():
            lines.append(f"| {name} | {case} | {r['person_frames']} | {r['boxes']} | {r['upper_iou50']:.3f} | "
                         f"{r['whole_iou50']:.3f} | {r['either_iou30']:.3f} | {r['ms_median']:.0f} |")
    return "\n".join(lines) + "\n"
