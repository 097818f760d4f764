"""SAEV on real video: trained without labels on PETS 2009 S2L1 frames 0-399, used as a person detector on
frames 400-794 through the Kalman tracker, and scored with MOTA like the HOG pipeline (docs/benchmarks_tracking.md).

The whole frame is shrunk to the SAEV input (64x64: people become 6-14 px tall). The keypoints are calibrated on
frames 0-399 against the ground truth's foot points (``keypoints.calibrate`` with the official Tsai camera:
which keypoints follow people, at what height on the body); on every frame the kept keypoints become ground
points, each drawn as a 1.7 m person's box for the same ``GroundTracker`` the HOG pipeline uses.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..datasets.pets import foot_points, load_ground_truth
from ..datasets.scoring import evaluate
from ..datasets.tsai import TsaiCamera
from ..tracking.pipeline import read_frames, track_detections
from ..tracking.tuning import PipelineParams
from .ae_train import AETrainParams, train_autoencoder
from .keypoints import KeypointDetector, calibrate, encode_keypoints

PETS_HEIGHTS = tuple(float(h) for h in np.round(np.arange(0.0, 1.75, 0.1), 2))
PERSON_HEIGHT = 1.7  # m, the box drawn for a detection
FPS = 7.0  # as tools/track.py is run on PETS (docs/benchmarks_tracking.md)


def load_video(path: Path, size: int, stop: int = 795) -> tuple[np.ndarray, tuple[int, int]]:
    """RGB frames (N, size, size, 3) uint8 of the whole picture, and the original (width, height)."""
    out, shape = [], (0, 0)
    for _, bgr in read_frames(path, 0, stop):
        shape = (bgr.shape[1], bgr.shape[0])
        out.append(cv2.cvtColor(cv2.resize(bgr, (size, size), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB))
    return np.asarray(out), shape


def ground_truth_positions(gt: np.ndarray, camera: TsaiCamera, frames: int, width: int, height: int
                           ) -> np.ndarray:
    """(frames, M, 2) ground positions (m) of the GT people whose foot point is inside the image, NaN-padded."""
    rows = [gt[(gt[:, 0] == f)] for f in range(frames)]
    m = max((len(r) for r in rows), default=1)
    out = np.full((frames, max(m, 1), 2), np.nan)
    for f, r in enumerate(rows):
        feet = foot_points(r[:, 2:6])
        inside = (feet[:, 0] >= 0) & (feet[:, 0] < width) & (feet[:, 1] >= 0) & (feet[:, 1] < height)
        out[f, :inside.sum()] = camera.image_to_ground(feet[inside])
    return out


def person_boxes(camera: TsaiCamera, xy: np.ndarray, aspect: float = 0.42) -> np.ndarray:
    """Boxes ``x, y, w, h, 1`` of 1.7 m people standing at ground points (n, 2)."""
    if not len(xy):
        return np.zeros((0, 5))
    foot = camera.world_to_image(np.column_stack([xy, np.zeros(len(xy))]))
    head = camera.world_to_image(np.column_stack([xy, np.full(len(xy), PERSON_HEIGHT)]))
    h = foot[:, 1] - head[:, 1]
    w = aspect * h
    return np.column_stack([foot[:, 0] - w / 2, head[:, 1], w, h, np.ones(len(xy))])


def pets_saev(video: Path, gt_file: Path, calib_file: Path, steps: int = 800, seed: int = 0, train_stop: int = 400,
              progress: Any = None) -> dict[str, Any]:
    """Train, calibrate on frames < ``train_stop``, track every frame; MOTA etc. per frame range."""
    camera = TsaiCamera.from_xml(calib_file)
    gt = load_ground_truth(gt_file)
    frames, (w, h) = load_video(video, 64)
    n = len(frames)
    data = {"frames": frames[:train_stop], "episode": np.zeros(train_stop, np.int32)}
    model, history = train_autoencoder(data, "saev", "cpu", AETrainParams(steps=steps, seed=seed,
                                                                          eval_every=max(1, steps // 4)), progress)
    scale = (w / 64.0, h / 64.0)
    uv, rho = encode_keypoints(model, frames)
    uv_full = (uv + 0.5) * np.asarray(scale) - 0.5

    def project(p: np.ndarray, z: float) -> np.ndarray:
        return camera.image_to_ground(p, z)

    truth = ground_truth_positions(gt, camera, n, w, h)
    calib = calibrate(uv_full[:train_stop], rho[:train_stop], truth[:train_stop], project, PETS_HEIGHTS,
                      max_error=1.0, good=0.7)
    det = KeypointDetector(model, calib, project, merge=0.7)
    dets = {f: person_boxes(camera, det.points(uv_full[f], rho[f])) for f in range(n)}
    params = PipelineParams()  # the tracker and box settings tuned for HOG on frames 0-399
    trk = dataclasses.replace(params.trk, birth_score=-math.inf)  # keypoints carry no SVM margin
    tracks = track_detections(dets, camera, 1.0 / FPS, trk, params.box)
    ranges = {"0-399": (0, train_stop), "400-794": (train_stop, n)}
    res = {name: evaluate(tracks, gt, camera, a, b) for name, (a, b) in ranges.items()}
    return {"results": res, "ae_steps": steps, "ae_seconds": history[-1]["seconds"],
            "final_val_reconstruction": history[-1]["val_reconstruction"],
            "calibration": {"keypoints": list(calib.keypoints), "heights_m": list(calib.heights),
                            "train_median_m": [round(v, 3) for v in calib.train_median_m]},
            "detections_per_frame": float(np.mean([len(d) for d in dets.values()]))}

