"""Timings for the tracking benchmark: tracker update with n targets, detector + tracker per frame."""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np

from ..perception.datasets.tsai import TsaiCamera
from ..perception.tracking.pipeline import GroundTracker, HogFgDetector
from ..perception.tracking.tracker import Tracker, TrackerParams
from ..perception.tracking.tuning import PipelineParams


def time_tracker_update(n_targets: int = 5, updates: int = 2000, seed: int = 0) -> dict[str, float]:
    """Mean and 95th-percentile wall time (ms) of ``Tracker.update`` with ``n_targets`` walkers."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-5, 5, (n_targets, 2))
    vel = rng.uniform(-1, 1, (n_targets, 2))
    trk = Tracker(TrackerParams(dt=0.1, birth_hits=1))
    times = []
    for k in range(updates):
        z = start + vel * 0.1 * k + rng.normal(0, 0.05, (n_targets, 2))
        t0 = time.perf_counter()
        trk.update(z)
        times.append(time.perf_counter() - t0)
    t = np.array(times[50:]) * 1000
    return {"n_targets": n_targets, "mean_ms": float(t.mean()), "p95_ms": float(np.percentile(t, 95)),
            "tracks": len(trk.tracks)}


def time_pipeline(frames: list[np.ndarray], camera: TsaiCamera, params: PipelineParams, size: tuple[int, int],
                  rescale_scales: bool, threads: int = 1) -> dict[str, float]:
    """Per-frame ms of HOG + foreground + tracker on ``frames`` resized to ``size`` (w, h), on ``threads``.

    ``rescale_scales`` divides the HOG scales by the resize factor (same person sizes searched, as tools/track.py
    --scale does); without it the scales apply to the small frame as they are (large people near a robot)."""
    old = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        f = size[0] / frames[0].shape[1]
        hog = params.hog
        if rescale_scales:
            hog = dataclasses.replace(hog, scales=tuple(s / f for s in hog.scales))
        det = HogFgDetector(hog)
        gt = GroundTracker(camera.scaled(f), params.trk, params.box, params.rng)
        times, det_t = [], []
        for fr in frames:
            img = cv2.resize(fr, size, interpolation=cv2.INTER_AREA)
            t0 = time.perf_counter()
            boxes = det(img)
            t1 = time.perf_counter()
            gt.step(boxes, 0.1)
            times.append(time.perf_counter() - t0)
            det_t.append(t1 - t0)
    finally:
        cv2.setNumThreads(old)
    t = np.array(times[3:]) * 1000
    return {"width": size[0], "height": size[1], "threads": threads, "hog_scales": list(hog.scales),
            "mean_ms": float(t.mean()), "p95_ms": float(np.percentile(t, 95)),
            "detector_mean_ms": float(np.mean(det_t[3:]) * 1000), "frames": len(t)}
