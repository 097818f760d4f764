"""SAEV keypoints as a person detector for the Kalman tracker (the design card's "SAEV with a Kalman tracker").

SAEV is trained without labels, so which keypoints follow people, and at what height on the body, is found
afterwards on training frames (``calibrate``): each keypoint's pixel is cast through the camera model onto
horizontal planes of several heights, and the height whose points land nearest to a visible member (median
distance) is the keypoint's; keypoints whose median stays above ``max_error`` are dropped, and each kept one gets
the presence threshold that best separates its good detections (within ``good`` of a member) from its bad ones.
The detector (``KeypointDetector``) then turns a frame's confident keypoints into ground points, merging those
closer than ``merge`` (two keypoints on one person), and the existing ``Tracker`` takes them as it takes boxes'
ground points. Heights near the camera's own are skipped: a ray at the optical centre's height never meets them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import torch

from ..camera import PinholeCamera, pixel_to_plane
from .autoencoders import SAEV, keypoint_pixels, to_input

HEIGHTS = (0.0, 0.15, 0.3, 0.45, 0.6, 0.75, 1.4, 1.55, 1.7)  # m; 0.9-1.3 m rays run nearly level


@dataclasses.dataclass(frozen=True)
class KeypointCalibration:
    """Kept keypoints with their plane height (m), presence threshold and training median error (m)."""

    keypoints: tuple[int, ...]
    heights: tuple[float, ...]
    thresholds: tuple[float, ...]
    train_median_m: tuple[float, ...]


def encode_keypoints(model: SAEV, frames: np.ndarray, batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Input-image pixels (N, K, 2) and presences (N, K) of uint8 frames (N, S, S, 3)."""
    uv, rho = [], []
    with torch.inference_mode():
        for i in range(0, len(frames), batch):
            code = model.eval().code(to_input(torch.from_numpy(np.ascontiguousarray(frames[i:i + batch]))))
            uv.append(keypoint_pixels(code[..., :2], model.size).numpy())
            rho.append(code[..., 2].numpy())
    return np.concatenate(uv), np.concatenate(rho)


def nearest_member_distance(points: np.ndarray, members: np.ndarray) -> np.ndarray:
    """Distance (N,) from each frame's point (N, 2) to its nearest member (N, M, 2; NaN = absent); NaN when
    the point is NaN or no member is present."""
    d = np.linalg.norm(members - points[:, None, :], axis=-1)
    with np.errstate(all="ignore"):
        out = np.nanmin(np.where(np.isnan(d), np.inf, d), axis=1)
    out[~np.isfinite(out)] = np.nan
    return out


Projection = Callable[[np.ndarray, float], np.ndarray]  # pixels (n, 2), plane height (m) -> points (n, 2), m


def plane_projection(cam: PinholeCamera) -> Projection:
    """The robot camera's ``pixel_to_plane`` as a ``Projection`` (robot frame)."""
    return lambda uv, h: pixel_to_plane(cam, uv, h)


def calibrate(uv: np.ndarray, rho: np.ndarray, visible: np.ndarray, project: Projection,
              heights: tuple[float, ...] = HEIGHTS, max_error: float = 0.5, good: float = 0.4
              ) -> KeypointCalibration:
    """Choose keypoints, heights and thresholds from training frames.

    ``uv`` (N, K, 2) and ``rho`` (N, K) from ``encode_keypoints``; ``visible`` (N, M, 2) the people in the
    camera's view (NaN otherwise) in the frame ``project`` maps to. Only frames with someone in view count."""
    seen = np.isfinite(visible[..., 0]).any(axis=1)
    kept: list[tuple[int, float, float, float]] = []
    for k in range(uv.shape[1]):
        best = (np.inf, 0.0, np.zeros(0))
        for h in heights:
            xy = project(uv[seen, k], h)
            err = nearest_member_distance(xy, visible[seen])
            if np.isfinite(err).sum() >= 10 and np.nanmedian(err) < best[0]:
                best = (float(np.nanmedian(err)), h, err)
        med, h, err = best
        if med > max_error:
            continue
        ok = np.isfinite(err)
        r, hit = rho[seen, k][ok], err[ok] <= good
        # threshold: the presence cut maximising good minus bad detections kept
        cuts = np.quantile(r, np.linspace(0.0, 0.95, 20))
        score = [int(hit[r >= c].sum()) - int((~hit[r >= c]).sum()) for c in cuts]
        kept.append((k, h, float(cuts[int(np.argmax(score))]), med))
    return KeypointCalibration(tuple(k for k, *_ in kept), tuple(h for _, h, _, _ in kept),
                               tuple(t for *_, t, _ in kept), tuple(m for *_, m in kept))


def merge_points(xy: np.ndarray, radius: float) -> np.ndarray:
    """Greedy merge of points (n, 2) closer than ``radius`` into their mean (keypoints on one person)."""
    out, used = [], np.zeros(len(xy), dtype=bool)
    for i in range(len(xy)):
        if used[i]:
            continue
        near = ~used & (np.linalg.norm(xy - xy[i], axis=1) < radius)
        used |= near
        out.append(xy[near].mean(axis=0))
    return np.asarray(out, dtype=float).reshape(-1, 2)


class KeypointDetector:
    """Frame (S, S, 3) uint8 -> ground points (n, 2) of people, from calibrated SAEV keypoints."""

    def __init__(self, model: SAEV, calib: KeypointCalibration, project: Projection, merge: float = 0.5) -> None:
        self.model, self.calib, self.project, self.merge = model.eval(), calib, project, merge

    def points(self, uv: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """One frame's keypoints (K, 2 pixels as ``project`` takes them) and presences (K,) -> ground points."""
        pts = [self.project(uv[k][None], h)[0]
               for k, h, t in zip(self.calib.keypoints, self.calib.heights, self.calib.thresholds, strict=True)
               if rho[k] >= t]
        xy = np.asarray(pts, dtype=float).reshape(-1, 2)
        return merge_points(xy[np.isfinite(xy[:, 0])], self.merge)

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        uv, rho = encode_keypoints(self.model, frame[None])
        return self.points(uv[0], rho[0])
