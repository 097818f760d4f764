"""Facing from MoveNet's keypoints on PETS S2L1 (``tools/bench_pets_facing.py``): each track's ``facing_deg``
(``tools/track.py``'s ``tracks_world.csv``) against the walking direction of the ground-truth person it follows,
where that person walks at ``MIN_SPEED`` or faster (walkers face where they go), and the same on a copy of the
video played backwards: there everyone walks backwards, so the walking direction flips but the facing must not,
and the truth stays the forward walking direction. The facing never reads motion; a tracker that took it from
the velocity would score ~180 deg off on the reversed copy.

Truth: ground positions from the GT boxes' foot points (the calibration), velocities by central differences over
``HALF_WINDOW`` frames each side. Tracks are matched to GT people per frame by ground distance (Hungarian, at
most ``GATE_M``).
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from ..perception.datasets.pets import load_ground_truth
from ..perception.datasets.tsai import TsaiCamera
from ..perception.tracking.pipeline import read_frames

MIN_SPEED = 0.5  # m/s: GT people walking at least this fast count
HALF_WINDOW = 3  # frames each side of the central difference (0.43 s at PETS' 7 frames/s)
GATE_M = 1.0  # m: a track farther than this from a GT person is not following them
TARGET_MEDIAN_DEG, TARGET_WITHIN, TARGET_WITHIN_DEG = 30.0, 0.8, 45.0


def gt_motion(gt: np.ndarray, camera: TsaiCamera, fps: float, half: int = HALF_WINDOW) -> np.ndarray:
    """GT rows ``frame, id, left, top, w, h, ...`` -> rows (n, 6) ``frame, id, x, y, vx, vy`` (m, m/s; NaN
    velocity where the person is not annotated ``half`` frames either side, fewer at the ends)."""
    gt = np.asarray(gt, dtype=float)
    xy = camera.image_to_ground(np.column_stack([gt[:, 2] + gt[:, 4] / 2, gt[:, 3] + gt[:, 5]]))
    out = np.column_stack([gt[:, :2], xy, np.full((len(gt), 2), np.nan)])
    for pid in np.unique(gt[:, 1]):
        idx = np.flatnonzero(gt[:, 1] == pid)
        idx = idx[np.argsort(gt[idx, 0])]
        f = gt[idx, 0]
        for k, i in enumerate(idx):
            a, b = max(k - half, 0), min(k + half, len(idx) - 1)
            if b > a and f[b] - f[a] == b - a:
                out[i, 4:6] = (xy[idx[b]] - xy[idx[a]]) * fps / (f[b] - f[a])
    return out


def facing_errors(tracks: np.ndarray, motion: np.ndarray, start: int, stop: int, min_speed: float = MIN_SPEED,
                  gate: float = GATE_M) -> dict[str, Any]:
    """Track rows ``frame, id, x, y, facing_deg`` (NaN unknown) against ``gt_motion`` rows on frames
    ``start <= f < stop``: the absolute angle (deg) between each matched track's facing and its GT person's
    walking direction, where that person walks at ``min_speed`` or faster; with how many such person-frames had
    a matched track, and one with a facing."""
    tracks = np.asarray(tracks, dtype=float).reshape(-1, 5)
    errors, fast, matched, known = [], 0, 0, 0
    by_frame = {int(f): tracks[tracks[:, 0] == f] for f in np.unique(tracks[:, 0])}
    for f in range(start, stop):
        g = motion[motion[:, 0] == f]
        g = g[np.hypot(g[:, 4], g[:, 5]) >= min_speed]
        fast += len(g)
        t = by_frame.get(f)
        if not len(g) or t is None or not len(t):
            continue
        d = np.hypot(g[:, None, 2] - t[None, :, 2], g[:, None, 3] - t[None, :, 3])
        rows, cols = linear_sum_assignment(np.where(d <= gate, d, 1e6))
        for r, c in zip(rows, cols, strict=True):
            if d[r, c] > gate:
                continue
            matched += 1
            if np.isfinite(t[c, 4]):
                known += 1
                walk = math.degrees(math.atan2(g[r, 5], g[r, 4]))
                errors.append(abs(math.remainder(t[c, 4] - walk, 360.0)))
    e = np.array(errors)
    return {"errors_deg": e, "walker_frames": fast, "matched": matched, "with_facing": known,
            **summarise(e)}


def summarise(e: np.ndarray) -> dict[str, float]:
    """Median and shares within 30 and 45 deg of errors ``e`` (deg); whether the targets are met."""
    if not len(e):
        return {"median_deg": math.nan, "within_30": math.nan, "within_45": math.nan, "meets_target": False}
    med, w45 = float(np.median(e)), float(np.mean(e <= TARGET_WITHIN_DEG))
    return {"median_deg": med, "within_30": float(np.mean(e <= 30.0)), "within_45": w45,
            "meets_target": bool(med <= TARGET_MEDIAN_DEG and w45 >= TARGET_WITHIN)}


def write_reversed(video: str | Path, start: int, stop: int, path: Path) -> int:
    """Frames ``start <= f < stop`` of ``video`` written to ``path`` last first (FFV1, lossless: the reversed
    copy's frames are the forward ones, pixel for pixel); returns how many. Decoded in chunks from the end, each
    from the start of the video (seeking is not frame-exact), so at most ``chunk`` frames are held at a time."""
    chunk = 60
    cap = cv2.VideoCapture(str(video))
    fps = cap.get(cv2.CAP_PROP_FPS) or 10.0
    cap.release()
    writer = None
    count = 0
    try:
        for hi in range(stop, start, -chunk):
            lo = max(hi - chunk, start)
            frames = [f for _, f in read_frames(video, lo, hi)]
            for frame in reversed(frames):
                if writer is None:
                    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps,
                                             (frame.shape[1], frame.shape[0]))
                writer.write(frame)
                count += 1
    finally:
        if writer is not None:
            writer.release()
    return count


def run(video: str | Path, calib: str | Path, gt_path: str | Path, start: int, stop: int, fps: float,
        params: dict[str, Any] | None = None, progress: bool = False) -> dict[str, Any]:
    """``tracking_io.track_video`` (tools/track.py's code path) over frames ``[start, stop)`` forward and over a
    reversed copy, each scored by ``facing_errors``; the reversed run's frames mapped back to the video's."""
    # lazy: optional, tools/track.py's code path needs motmetrics (the tracking extra)
    from ..perception.tracking.tracking_io import read_world, track_video

    camera = TsaiCamera.from_xml(calib)
    motion = gt_motion(load_ground_truth(gt_path), camera, fps)
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="pets-facing-") as tmp:
        rev = Path(tmp) / "reversed.avi"
        n = write_reversed(video, start, stop, rev)
        for name, path, first in (("forward", Path(video), start), ("reversed", rev, 0)):
            d = Path(tmp) / name
            d.mkdir()
            run_info = track_video(path, calib, d, start=first, stop=first + n, fps=fps, overlay=False,
                                   progress=progress, params=params)
            w = read_world(d / "tracks_world.csv")
            frames = w[:, 0] if name == "forward" else start + n - 1 - w[:, 0]
            tracks = np.column_stack([frames, w[:, 1], w[:, 2], w[:, 3], w[:, 6]])
            res = facing_errors(tracks, motion, start, start + n)
            res["errors_deg"] = [round(float(v), 1) for v in res["errors_deg"]]
            out[name] = {"facing": res, "run": run_info}
    return out


def markdown(report: dict[str, Any]) -> str:
    """The benchmark's table."""
    lines = [f"PETS S2L1 frames {report['start']}-{report['stop'] - 1}, `{report['command']}`"
             f"{' (commit ' + report['commit'] + ')' if report.get('commit') else ''}: each track's `facing_deg` "
             f"against its GT person's walking direction where they walk at >= {MIN_SPEED} m/s (matched within "
             f"{GATE_M} m on the ground). Reversed: the same frames played backwards (everyone walks backwards; "
             f"the truth stays the forward walking direction). Target: median <= {TARGET_MEDIAN_DEG:.0f} deg, >= "
             f"{TARGET_WITHIN:.0%} within {TARGET_WITHIN_DEG:.0f} deg.", "",
             "| video | median error (deg) | within 30 deg | within 45 deg | walker-frames with a facing | "
             "ms/frame | target met |", "|---|---|---|---|---|---|---|"]
    for name in ("forward", "reversed"):
        r = report[name]["facing"]
        ms = report[name]["run"]["ms_per_frame"]
        met = "yes" if r["meets_target"] else "no"
        lines.append(f"| {name} | {r['median_deg']:.1f} | {r['within_30']:.0%} | {r['within_45']:.0%} | "
                     f"{r['with_facing']} of {r['walker_frames']} | {ms:.0f} | {met} |")
    return "\n".join(lines) + "\n"
