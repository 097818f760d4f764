"""File-level tracking runs behind tools/track.py and tools/eval_tracking.py: inputs checked up front,
outputs (MOT text, world CSV, overlay video, metrics JSON/Markdown) written into a given folder."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ...cli import make_bar
from ...errors import UserError
from ..datasets.occlusion import FeetHidden, median_background
from ..datasets.pets import GroundTruthError, load_ground_truth, load_mot
from ..datasets.scoring import evaluate
from ..datasets.tsai import CalibrationError, TsaiCamera
from ..detection.keypoints import KEYPOINTS
from ..detection.learned import SsdDetector
from ..detection.movenet import PEOPLE_COLUMNS, selected
from ..detection.ranging import HEAD
from .pipeline import GroundTracker, HogFgDetector, VideoError, open_video, read_frames
from .tuning import PipelineParams, default_params


class InputError(UserError):
    """Bad input file or parameter; the message names the file and what was expected."""


DEFAULT_DETECTOR = "movenet"  # the only one meeting every PETS target, feet in view and hidden (docs/tracking.md)


def _params(data: dict[str, Any] | None, detector: str | None = None) -> PipelineParams:
    if data is None:
        return default_params(detector or DEFAULT_DETECTOR)
    try:
        pp = PipelineParams.from_dict(data)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"pipeline parameters: {exc}; expected keys hog, trk, box (and detector, ssd) as written "
                         f"by tools/bench_tracking.py") from exc
    if detector is not None and detector != pp.detector:
        raise InputError(f"pipeline parameters are for detector {pp.detector!r}, not {detector!r}: leave --detector "
                         f"out or give parameters written for it")
    return pp


def load_inputs(video: str | Path, calib: str | Path) -> tuple[tuple[int, float, tuple[int, int]], TsaiCamera]:
    """Open the video and the calibration, converting their errors to ``InputError``."""
    try:
        cap, n, fps, size = open_video(video)
        cap.release()
        cam = TsaiCamera.from_xml(calib)
    except (VideoError, CalibrationError) as exc:
        raise InputError(str(exc)) from exc
    return (n, fps, size), cam


class Inset:
    """Top-down inset: ground positions (m) inside the ground area the camera sees, drawn into a square."""

    def __init__(self, cam: TsaiCamera, size: tuple[int, int], px: int = 220) -> None:
        w, h = size
        # the ground seen by the image below 30 % of its height (the horizon side is far and uninformative)
        edge = np.array([[0, 0.3], [0.5, 0.3], [1, 0.3], [1, 0.65], [1, 1], [0.5, 1], [0, 1], [0, 0.65]])
        self.footprint = cam.image_to_ground(edge * [w, h])
        self.lo = self.footprint.min(axis=0)
        self.span = float((self.footprint.max(axis=0) - self.lo).max())
        self.px = px

    def _pix(self, xy: np.ndarray, x0: int, y0: int) -> np.ndarray:
        q = (np.asarray(xy) - self.lo) / self.span * (self.px - 1)
        return np.stack([x0 + q[..., 0], y0 + self.px - 1 - q[..., 1]], axis=-1).astype(np.int32)

    def draw(self, img: np.ndarray, tracks: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]) -> None:
        p = self.px
        x0, y0 = img.shape[1] - p - 5, 5
        roi = img[y0:y0 + p, x0:x0 + p]
        roi[:] = (roi * 0.25 + 30).astype(np.uint8)
        cv2.rectangle(img, (x0, y0), (x0 + p - 1, y0 + p - 1), (255, 255, 255), 1)
        cv2.polylines(img, [self._pix(self.footprint, x0, y0)], True, (160, 160, 160), 1)
        for tid, _, xy, v in tracks:
            c = tuple(int(v) for v in self._pix(xy, x0, y0))
            if not (x0 <= c[0] < x0 + p and y0 <= c[1] < y0 + p):
                continue
            col = colour(tid)
            cv2.circle(img, c, 3, col, -1)
            tip = (int(c[0] + v[0] / self.span * p), int(c[1] - v[1] / self.span * p))  # 1 s ahead
            cv2.line(img, c, tip, col, 1)


def colour(tid: int) -> tuple[int, int, int]:
    rng = np.random.default_rng(tid)
    return tuple(int(v) for v in rng.integers(60, 256, 3))  # type: ignore[return-value]


def make_detector(pp: PipelineParams, scale: float = 1.0) -> Callable[[np.ndarray], np.ndarray]:
    """The detector ``pp.detector`` names, for BGR frames resized by ``scale`` (same person sizes searched)."""
    if pp.detector == "ssd":
        return SsdDetector(dataclasses.replace(pp.ssd, min_height=pp.ssd.min_height * scale))
    if pp.detector == "movenet":
        return selected(dataclasses.replace(pp.ssd, min_height=pp.ssd.min_height * scale))
    hog = pp.hog
    if scale != 1.0:  # search the same person sizes on the resized frame
        hog = dataclasses.replace(hog, scales=tuple(s / scale for s in hog.scales),
                                  min_height=hog.min_height * scale)
    return HogFgDetector(hog)


def track_video(video: str | Path, calib: str | Path, out_dir: str | Path, start: int = 0,
                stop: int | None = None, scale: float = 1.0, params: dict[str, Any] | None = None,
                fps: float | None = None, overlay: bool = True, progress: bool = True,
                detector: str | None = None, hide_feet: str | Path | None = None) -> dict[str, Any]:
    """Run detector + tracker over ``video`` and write the three outputs into ``out_dir`` (must exist).

    ``detector``: "movenet" (default), "ssd" or "hog", with its built-in thresholds unless ``params`` are given.
    ``hide_feet``: a ground-truth file; each of its boxes is painted from 55 % of its height down with the
    video's median background before detection (``occlusion.FeetHidden``)."""
    (n, vfps, size), cam = load_inputs(video, calib)
    pp = _params(params, detector)
    painter = None
    if hide_feet is not None:
        try:
            painter = FeetHidden(load_ground_truth(hide_feet), median_background(video))
        except GroundTruthError as exc:
            raise InputError(str(exc)) from exc
    if not scale > 0:
        raise InputError(f"--scale = {scale}: expected > 0")
    if start < 0 or (stop is not None and stop <= start):
        raise InputError(f"frame range [{start}, {stop}): expected 0 <= start < stop")
    dt = 1.0 / (fps or vfps)
    det = make_detector(pp, scale)
    gt = GroundTracker(cam, pp.trk, pp.box, pp.rng)
    out = Path(out_dir)
    mot, world = [], []
    writer = None
    inset = Inset(cam, size)
    total = (min(n, stop) if stop is not None else n) - start
    bar = None
    if progress:
        bar = make_bar(max(total, 0), Path(video).name, "frame")
    t_proc, count, n_boxes, n_head, n_looks = 0.0, 0, 0, 0, 0
    try:
        for i, frame in read_frames(video, start, stop):
            if painter is not None:
                frame = painter(i, frame)
            t0 = time.perf_counter()
            small = frame if scale == 1.0 else cv2.resize(frame, None, fx=scale, fy=scale,
                                                          interpolation=cv2.INTER_AREA)
            boxes = det(small)
            boxes[:, :4] /= scale
            if boxes.shape[1] >= PEOPLE_COLUMNS:  # keypoints' x and y too
                boxes[:, 5:PEOPLE_COLUMNS] /= np.tile([scale, scale, 1.0], len(KEYPOINTS))
            tracks = gt.step(boxes, dt)
            if hasattr(det, "look"):  # close looks at a few people a frame, for their facing (MoveNet)
                seen = []
                for tid, k in gt.choose_looks(boxes, det.look_height(small.shape[0]) / scale, det.looks):
                    kp = det.look(small, boxes[k, :4] * scale)
                    if kp is not None:
                        kp[:, :2] /= scale
                        seen.append((tid, kp))
                gt.look(seen)
                n_looks += len(seen)
            t_proc += time.perf_counter() - t0
            n_boxes += len(boxes)
            n_head += int((gt.cues == HEAD).sum())
            count += 1
            for tid, bb, xy, v in tracks:
                mot.append((i + 1, tid, *bb, 1, -1, -1, -1))
                world.append((i, tid, *xy, *v, math.degrees(gt.facing_of(tid)[0])))
            if overlay:
                if writer is None:
                    writer = cv2.VideoWriter(str(out / "overlay.mp4"), cv2.VideoWriter_fourcc(*"mp4v"),
                                             1.0 / dt, (frame.shape[1], frame.shape[0]))
                draw(frame, tracks, inset)
                writer.write(frame)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.release()
    if count == 0:
        raise InputError(f"{video}: no frames in [{start}, {stop})")
    np.savetxt(out / "tracks_mot.txt", np.array(mot).reshape(-1, 10),
               fmt=["%d", "%d", "%.2f", "%.2f", "%.2f", "%.2f", "%d", "%d", "%d", "%d"], delimiter=",")
    write_world(out / "tracks_world.csv", np.array(world).reshape(-1, 7))
    return {"frames": count, "tracks": len({r[1] for r in mot}), "ms_per_frame": 1000 * t_proc / count,
            "start": start, "stop": start + count, "scale": scale, "dt": dt, "detector": pp.detector,
            "feet_hidden": hide_feet is not None, "head_ranged": int(n_head), "boxes": int(n_boxes),
            "looks": int(n_looks)}


WORLD_HEADER = "frame,id,x_m,y_m,vx,vy,facing_deg"


def write_world(path: Path, rows: np.ndarray) -> None:
    """``tracks_world.csv``: rows ``frame, id, x_m, y_m, vx, vy, facing_deg`` (frame 0-based; metres and m/s in
    the calibration's ground frame; facing_deg the direction the chest faces, atan2 in that frame, empty where
    unknown)."""
    lines = [WORLD_HEADER]
    for f, tid, x, y, vx, vy, fd in np.asarray(rows, dtype=float).reshape(-1, 7):
        lines.append(f"{int(f)},{int(tid)},{x:.4f},{y:.4f},{vx:.4f},{vy:.4f}," + (f"{fd:.1f}" if np.isfinite(fd)
                                                                                    else ""))
    path.write_text("\n".join(lines) + "\n")


def read_world(path: Path) -> np.ndarray:
    """``tracks_world.csv`` -> rows (n, 7) ``frame, id, x_m, y_m, vx, vy, facing_deg`` (NaN where empty or where
    the file has no facing column); ``InputError`` naming the file otherwise."""
    try:
        lines = path.read_text().splitlines()
        head = lines[0].split(",") if lines else []
        if head[:6] != WORLD_HEADER.split(",")[:6]:
            raise ValueError(f"header {lines[0] if lines else ''!r}")
        rows = [[float(v) if v.strip() else np.nan for v in ln.split(",")] for ln in lines[1:] if ln.strip()]
        rows = [r + [np.nan] * (7 - len(r)) for r in rows]
        if any(len(r) != 7 for r in rows):
            raise ValueError("a row with more than 7 fields")
    except (OSError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: cannot parse ({exc}); expected {WORLD_HEADER}") from exc
    return np.array(rows, dtype=float).reshape(-1, 7)


def draw(frame: np.ndarray, tracks: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]], inset: Inset) -> None:
    for tid, bb, _, _ in tracks:
        x, y, w, h = (int(round(v)) for v in bb)
        cv2.rectangle(frame, (x, y), (x + w, y + h), colour(tid), 2)
        cv2.putText(frame, str(tid), (x, y - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour(tid), 2)
    inset.draw(frame, tracks)


def load_tracks(track_dir: str | Path) -> np.ndarray:
    """``tracks_mot.txt`` (+ ``tracks_world.csv`` when present) -> rows ``frame(0-based), id, l, t, w, h,
    x_m, y_m`` (world columns NaN when absent)."""
    d = Path(track_dir)
    mot_path = d / "tracks_mot.txt"
    try:
        mot = load_mot(mot_path)
    except GroundTruthError as exc:
        raise InputError(str(exc)) from exc
    rows = np.column_stack([mot[:, :6], np.full((len(mot), 2), np.nan)])
    wpath = d / "tracks_world.csv"
    if wpath.is_file() and len(mot):
        w = read_world(wpath)
        lookup = {(int(r[0]), int(r[1])): r[2:4] for r in w}
        for k, r in enumerate(rows):
            xy = lookup.get((int(r[0]), int(r[1])))
            if xy is not None:
                rows[k, 6:8] = xy
    return rows


def evaluate_dir(track_dir: str | Path, gt_path: str | Path, calib: str | Path | None,
                 ranges: list[tuple[int, int | None]]) -> dict[str, dict[str, Any]]:
    """Metrics for each frame range ``[start, stop)`` (stop None = end of the GT)."""
    try:
        gt = load_ground_truth(gt_path)
        cam = TsaiCamera.from_xml(calib) if calib is not None else None
    except (GroundTruthError, CalibrationError) as exc:
        raise InputError(str(exc)) from exc
    tracks = load_tracks(track_dir)
    if np.isnan(tracks[:, 6]).any():
        tracks = tracks[:, :6]  # project box foot points instead
    out = {}
    for a, b in ranges:
        stop = int(gt[:, 0].max()) + 1 if b is None else b
        out[f"frames {a}-{stop - 1}"] = evaluate(tracks, gt, cam, a, stop)
    return out
