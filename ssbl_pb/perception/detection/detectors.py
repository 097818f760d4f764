"""Person detectors behind one interface: ``detector(frame) -> (n, 5)`` boxes ``x, y, w, h, score`` (pixels).

- ``HogDetector``: OpenCV's HOG + linear SVM people detector (weights ship inside OpenCV) run at a few fixed
  image scales; each 64x128 window is shrunk to the person inside it, overlapping boxes are merged by
  non-maximum suppression, and an optional background-subtraction check drops boxes on static background.
- ``SimDetector``: the human proxies' boxes from PyBullet's segmentation mask (ground truth for the renderer).
- ``ColourDetector``: the proxies from RGB alone (their torsos are saturated colours; room and robot are grey).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Protocol

import cv2
import numpy as np

from ...errors import UserError


class Detector(Protocol):
    def __call__(self, frame: np.ndarray) -> np.ndarray:
        """BGR/RGB uint8 (H, W, 3) -> (n, 5) float boxes ``x, y, w, h, score``."""
        ...


def nms(boxes: np.ndarray, iou_thresh: float) -> np.ndarray:
    """Greedy non-maximum suppression on ``x, y, w, h, score`` rows; returns the kept rows, best first."""
    if len(boxes) == 0:
        return boxes.reshape(0, 5)
    order = np.argsort(-boxes[:, 4])
    keep = []
    x1, y1 = boxes[:, 0], boxes[:, 1]
    x2, y2 = x1 + boxes[:, 2], y1 + boxes[:, 3]
    area = boxes[:, 2] * boxes[:, 3]
    while len(order):
        i = order[0]
        keep.append(i)
        rest = order[1:]
        iw = np.clip(np.minimum(x2[i], x2[rest]) - np.maximum(x1[i], x1[rest]), 0, None)
        ih = np.clip(np.minimum(y2[i], y2[rest]) - np.maximum(y1[i], y1[rest]), 0, None)
        inter = iw * ih
        iou = inter / (area[i] + area[rest] - inter)
        order = rest[iou <= iou_thresh]
    return boxes[keep]


@dataclasses.dataclass(frozen=True)
class HogParams:
    """HOG detector settings (thresholds are chosen on PETS frames 0-399 by tools/bench_tracking.py)."""

    scales: tuple[float, ...] = (1.0, 1.3, 1.6)  # image upscales; a person of h px fills the window at ~96/h
    hit_threshold: float = 0.0  # SVM margin for a window to count
    win_stride: int = 8  # px
    shrink_x: float = 0.25  # fraction of the window width cut from each side (64 px window -> 32 px person)
    shrink_top: float = 0.1  # fraction of the window height cut above the head
    shrink_bottom: float = 0.1  # ... and below the feet
    nms_iou: float = 0.3
    fg_min: float = 0.0  # minimum foreground fraction inside a box (0 = no foreground check)
    fg_history: int = 200  # background model memory (frames)
    min_height: float = 0.0  # px, smaller boxes are dropped (after scaling back to the frame)

    def __post_init__(self) -> None:
        if not self.scales or any(not s > 0 for s in self.scales):
            raise UserError(f"hog.scales = {self.scales!r}: expected positive numbers")
        for name in ("shrink_x", "shrink_top", "shrink_bottom"):
            v = getattr(self, name)
            if not 0 <= v < 0.5:
                raise UserError(f"hog.{name} = {v!r}: expected in [0, 0.5)")
        if not 0 <= self.fg_min <= 1:
            raise UserError(f"hog.fg_min = {self.fg_min!r}: expected in [0, 1]")
        if not (isinstance(self.win_stride, int) and self.win_stride > 0):
            raise UserError(f"hog.win_stride = {self.win_stride!r}: expected a positive integer")


def shrink_windows(win: np.ndarray, p: HogParams) -> np.ndarray:
    """HOG windows ``x, y, w, h, score`` -> the person's box inside each (``p.shrink_*`` cut from the sides)."""
    win = np.asarray(win, dtype=float).reshape(-1, 5)
    return np.column_stack([win[:, 0] + p.shrink_x * win[:, 2], win[:, 1] + p.shrink_top * win[:, 3],
                            win[:, 2] * (1 - 2 * p.shrink_x), win[:, 3] * (1 - p.shrink_top - p.shrink_bottom),
                            win[:, 4]])


class HogDetector:
    """HOG people detector at fixed scales with an optional foreground check (stateful: call once per frame)."""

    def __init__(self, params: HogParams | None = None) -> None:
        self.params = params or HogParams()
        self.hog = cv2.HOGDescriptor()
        self.hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
        self.bg = (cv2.createBackgroundSubtractorMOG2(history=self.params.fg_history, detectShadows=False)
                   if self.params.fg_min > 0 else None)
        self.last_fg: np.ndarray | None = None

    def raw(self, frame: np.ndarray) -> np.ndarray:
        """Shrunk boxes of all windows above the threshold, before NMS/foreground (``x, y, w, h, score``)."""
        p = self.params
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
        out = []
        for s in p.scales:
            img = gray if s == 1.0 else cv2.resize(gray, None, fx=s, fy=s, interpolation=cv2.INTER_LINEAR)
            if img.shape[0] < 128 or img.shape[1] < 64:
                continue
            loc, w = self.hog.detect(img, hitThreshold=p.hit_threshold, winStride=(p.win_stride, p.win_stride),
                                     padding=(8, 8))
            if len(loc) == 0:
                continue
            loc = np.asarray(loc, dtype=float).reshape(-1, 2)
            win = np.column_stack([loc / s, np.full(len(loc), 64.0 / s), np.full(len(loc), 128.0 / s),
                                   np.asarray(w, dtype=float).reshape(-1)])
            out.append(shrink_windows(win, p))
        return np.concatenate(out) if out else np.zeros((0, 5))

    def foreground(self, frame: np.ndarray) -> np.ndarray:
        """Update the background model; the foreground mask (H, W) as 0/1 float32."""
        if self.bg is None:
            raise ValueError("foreground check is off (hog.fg_min = 0)")
        mask = self.bg.apply(frame)
        self.last_fg = (mask > 0).astype(np.float32)
        return self.last_fg

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        p = self.params
        boxes = self.raw(frame)
        if p.min_height > 0:
            boxes = boxes[boxes[:, 3] >= p.min_height]
        boxes = nms(boxes, p.nms_iou)
        if self.bg is not None:
            fg = self.foreground(frame)
            frac = box_fractions(fg, boxes)
            boxes = boxes[frac >= p.fg_min]
        return boxes


def box_fractions(mask: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Mean of ``mask`` (H, W) inside each ``x, y, w, h`` box (clipped to the image), via an integral image."""
    if len(boxes) == 0:
        return np.zeros(0)
    ii = cv2.integral(mask.astype(np.float32), sdepth=cv2.CV_64F)
    h, w = mask.shape
    x1 = np.clip(np.round(boxes[:, 0]), 0, w).astype(int)
    y1 = np.clip(np.round(boxes[:, 1]), 0, h).astype(int)
    x2 = np.clip(np.round(boxes[:, 0] + boxes[:, 2]), 0, w).astype(int)
    y2 = np.clip(np.round(boxes[:, 1] + boxes[:, 3]), 0, h).astype(int)
    area = np.maximum((x2 - x1) * (y2 - y1), 1)
    total = ii[y2, x2] - ii[y1, x2] - ii[y2, x1] + ii[y1, x1]
    return total / area


def mask_boxes(mask: np.ndarray, labels: Sequence[int], min_pixels: int = 4) -> np.ndarray:
    """One ``x, y, w, h, 1`` box per label present in an integer mask (rows follow ``labels``; absent -> NaN)."""
    out = np.full((len(labels), 5), np.nan)
    for i, lab in enumerate(labels):
        ys, xs = np.nonzero(mask == lab)
        if len(xs) >= min_pixels:
            out[i] = (xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1, 1.0)
    return out


class SimDetector:
    """Boxes of the human proxies from the segmentation mask: call with ``(rgb, seg)`` from
    ``World.render_first_person(w, h, segmentation=True)``. ``body_ids`` are ``world.human_ids``."""

    def __init__(self, body_ids: Sequence[int], min_pixels: int = 4) -> None:
        self.body_ids = list(body_ids)
        self.min_pixels = min_pixels

    def with_index(self, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (n, 5) and which member each belongs to (n,)."""
        boxes = mask_boxes(seg, self.body_ids, self.min_pixels)
        ok = ~np.isnan(boxes[:, 0])
        return boxes[ok], np.flatnonzero(ok)

    def __call__(self, frame: tuple[np.ndarray, np.ndarray]) -> np.ndarray:  # type: ignore[override]
        _, seg = frame
        if seg is None:
            raise ValueError("SimDetector needs the segmentation mask: render with segmentation=True")
        return self.with_index(seg)[0]


@dataclasses.dataclass(frozen=True)
class ColourParams:
    """Saturated-colour blob detector for the proxies (RGB frames)."""

    min_saturation: int = 90  # HSV S (0-255) of the proxies' torsos; room, walls, skin and Pepper are below
    min_value: int = 40
    hue_tol: int = 8  # OpenCV hue units (0-180) around each palette colour
    min_area: int = 12  # px
    merge_gap: int = 2  # px closing so a torso split by the facing marker stays one blob


class ColourDetector:
    """Proxies' torso boxes from RGB. With a ``palette`` (the members' RGB colours, 0-1) each colour is
    segmented on its own, so touching members stay apart; without, all saturated pixels form the blobs."""

    def __init__(self, palette: Sequence[Sequence[float]] | None = None, params: ColourParams | None = None) -> None:
        self.params = params or ColourParams()
        self.hues = None
        if palette is not None:
            rgb = np.clip(np.asarray(palette, dtype=float)[:, :3] * 255, 0, 255).astype(np.uint8)[None]
            self.hues = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[0, :, 0].astype(int)

    def _blobs(self, mask: np.ndarray, out: list) -> None:
        p = self.params
        mask = mask.astype(np.uint8)
        if p.merge_gap > 0:
            k = np.ones((2 * p.merge_gap + 1, 2 * p.merge_gap + 1), np.uint8)
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, k)
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        for i in range(1, n):
            x, y, w, h, area = stats[i]
            if area >= p.min_area:
                out.append((x, y, w, h, 1.0))

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        p = self.params
        hsv = cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2HSV)
        sat = (hsv[..., 1] >= p.min_saturation) & (hsv[..., 2] >= p.min_value)
        out: list = []
        if self.hues is None:
            self._blobs(sat, out)
        else:
            hue = hsv[..., 0].astype(int)
            for h0 in self.hues:
                d = np.abs(hue - h0)
                self._blobs(sat & (np.minimum(d, 180 - d) <= p.hue_tol), out)
        return np.array(out, dtype=float).reshape(-1, 5)
