"""Video -> detections -> ground plane -> tracks, for a static calibrated camera (PETS-style).

Detection is split in two so thresholds can be tuned without re-running HOG: ``detect_raw`` stores every HOG
window above a low margin with its foreground fraction, and ``select`` applies the thresholds, shrinking and
NMS. ``GroundTracker`` projects foot points with the camera, runs the Kalman tracker and returns each track's
image box drawn from its ground position and a per-track body height (so coasting tracks keep a box).
Detections with keypoints (MoveNet's people rows, ``movenet.people``) are ranged from them when cut above the
feet, and give each track its facing (``keypoints.facing_posterior`` per detection and per close look, ``look``;
filtered per track by ``keypoints.FacingTrack``: ``facing_of``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from ...errors import UserError
from ..datasets.tsai import TsaiCamera
from ..detection.detectors import HogDetector, HogParams, box_fractions, nms, shrink_windows
from ..detection.keypoints import BodyParams, FacingTrack, facing_posterior
from ..detection.movenet import split
from ..detection.ranging import FEET, HEAD, RangingParams, TsaiGeometry, range_boxes
from .tracker import Tracker, TrackerParams

FG_SHRINK = HogParams(shrink_x=0.3, shrink_top=0.12, shrink_bottom=0.12)  # box used for foreground fractions


class VideoError(UserError):
    """A video cannot be opened or read; the message names the file."""


def open_video(path: str | Path) -> tuple[cv2.VideoCapture, int, float, tuple[int, int]]:
    """Open a video; returns (capture, frame count, fps, (width, height)). Raises VideoError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise VideoError(f"{path}: video file not found")
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise VideoError(f"{path}: cannot be opened as a video (expected a file OpenCV/FFmpeg can decode)")
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    fps = float(cap.get(cv2.CAP_PROP_FPS)) or 10.0
    size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    ok, _ = cap.read()
    if not ok:
        cap.release()
        raise VideoError(f"{path}: opened but no frame could be decoded (expected a video with frames)")
    cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
    return cap, n, fps, size


def read_frames(path: str | Path, start: int = 0, stop: int | None = None,
                scale: float = 1.0) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(index, BGR frame)`` for frames ``start <= index < stop``, resized by ``scale``.

    Frames are decoded from 0 so that index i is exactly the i-th frame (seeking is not frame-exact)."""
    cap, _, _, _ = open_video(path)
    try:
        i = 0
        while stop is None or i < stop:
            ok, frame = cap.read()
            if not ok:
                break
            if i >= start:
                if scale != 1.0:
                    frame = cv2.resize(frame, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
                yield i, frame
            i += 1
    finally:
        cap.release()


class HogFgDetector:
    """HOG windows plus a background model: ``windows`` gives raw rows ``x, y, w, h, score, fg`` (``fg`` is the
    foreground fraction inside the window shrunk by ``FG_SHRINK``); calling it applies ``select``.

    ``raw_threshold`` (default: the params' threshold) is the SVM margin kept in ``windows``; a low one lets
    a cache of windows serve many thresholds. Call once per frame, in order (the background model learns)."""

    def __init__(self, params: HogParams, raw_threshold: float | None = None, fg_history: int = 200) -> None:
        self.params = params
        thr = params.hit_threshold if raw_threshold is None else raw_threshold
        self.hog = HogDetector(dataclasses.replace(params, shrink_x=0.0, shrink_top=0.0, shrink_bottom=0.0,
                                                   fg_min=0.0, hit_threshold=thr, min_height=0.0))
        self.bg = cv2.createBackgroundSubtractorMOG2(history=fg_history, detectShadows=False)

    def windows(self, frame: np.ndarray) -> np.ndarray:
        win = self.hog.raw(frame)
        fg = (self.bg.apply(frame) > 0).astype(np.float32)
        return np.column_stack([win, box_fractions(fg, shrink_windows(win, FG_SHRINK))])

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return select(self.windows(frame), self.params)


def detect_raw(frames: Iterator[tuple[int, np.ndarray]], params: HogParams,
               raw_threshold: float | None = None) -> dict[int, np.ndarray]:
    """``HogFgDetector.windows`` for every frame: ``{index: (n, 6) rows}``."""
    det = HogFgDetector(params, raw_threshold)
    return {i: det.windows(frame) for i, frame in frames}


def select(raw: np.ndarray, params: HogParams) -> np.ndarray:
    """Apply threshold, foreground check, shrink, minimum height and NMS to ``detect_raw`` rows."""
    raw = np.asarray(raw, dtype=float).reshape(-1, 6)
    keep = raw[:, 4] >= params.hit_threshold
    if params.fg_min > 0:
        keep &= raw[:, 5] >= params.fg_min
    boxes = shrink_windows(raw[keep, :5], params)
    if params.min_height > 0:
        boxes = boxes[boxes[:, 3] >= params.min_height]
    return nms(boxes, params.nms_iou)


@dataclasses.dataclass(frozen=True)
class BoxParams:
    """How a track's image box is drawn from its ground position."""

    default_height: float = 1.7  # m, body height before any detection has measured it
    height_range: tuple[float, float] = (1.3, 2.1)  # m, clip for measured heights
    height_gain: float = 0.2  # EMA gain of the per-track height
    aspect: float = 0.42  # box width / box height
    max_coast: int = 3  # report a track's box for at most this many frames without a detection
    max_coast_inside: int = 0  # ... or this many when the track has >= 10 hits and its box is inside the frame
    #                            (occlusion rather than leaving), if larger than max_coast
    det_weight: float = 0.0  # weight of the matched detection's own box against the drawn one (0 = drawn)
    pixel_noise: float = 0.0  # foot-point noise as a fraction of box height; > 0 gives each detection a
    #                           covariance through the projection's Jacobian (depth error grows with range);
    #                           the head cue's noise is ``RangingParams.pixel_noise`` (of the box's width)
    head_ranging: bool = False  # boxes cut above the feet (or by the image's bottom) ranged from the head row and
    #                             the box's width (``ranging.range_boxes``), with that cue's covariance
    # a track's facing (``keypoints.FacingTrack``), chosen on PETS frames 0-399 (docs/tracking.md): it may turn
    # by 0.75 rad/s (a walker's U-turn takes ~4 s); each detection's posterior counts a tenth of a close look's
    # (``GroundTracker.look``: the keypoints of a person 40 px tall are twice as far off as a look's), each mixed
    # with 5 % of a uniform (no frame rules a facing out)
    facing_turn_std: float = 0.75  # rad/s
    facing_weight: float = 0.1  # power each detection's facing posterior is raised to before it multiplies in
    look_weight: float = 1.0  # the same for a close look's
    facing_floor: float = 0.05  # share of a uniform mixed into each facing posterior
    # close looks go to tracks whose facing is unsure, or not looked at for a second: on frames 0-399 as accurate
    # as looking at two people every frame, with a third fewer looks
    look_std: float = 0.61  # rad (35 deg)
    look_every: int = 7  # steps


class GroundTracker:
    """Tracker on the ground plane of a calibrated static camera; ``step`` takes one frame's image boxes."""

    def __init__(self, camera: TsaiCamera, params: TrackerParams | None = None,
                 box: BoxParams | None = None, ranging: RangingParams | None = None,
                 body: BodyParams | None = None) -> None:
        self.camera = camera
        self.geometry = TsaiGeometry(camera)
        self.tracker = Tracker(params)
        self.box = box or BoxParams()
        self.ranging = ranging or RangingParams()
        self.body = body or BodyParams()
        self.cues = np.zeros(0, dtype=int)  # the last step's cue per box (``ranging.FEET`` / ``HEAD``)
        self.heights: dict[int, float] = {}
        self.aspects: dict[int, float] = {}
        self.facing: dict[int, FacingTrack] = {}  # track id -> its facing filter
        self.detected: dict[int, int] = {}  # track id -> the index of its detection in the last step
        self.looked: dict[int, int] = {}  # track id -> the step of its last close look (``look``)
        self.steps = 0

    def facing_of(self, tid: int) -> tuple[float, float]:
        """Track ``tid``'s facing: yaw (rad, atan2 in the camera's ground frame) and std (rad); NaN and inf while
        unknown (no keypoint facing yet, or spread wider than ``BodyParams.max_std_deg``)."""
        ft = self.facing.get(tid)
        return ft.estimate() if ft is not None else (math.nan, math.inf)

    def choose_looks(self, boxes: np.ndarray, max_height: float = math.inf, count: int = 1) -> list[tuple[int, int]]:
        """The tracks to look at closely this step (``look``): of those detected in it whose box (``boxes``, the
        step's) is shorter than ``max_height`` px and whose facing is unsure (std above ``box.look_std``) or was
        last looked at ``box.look_every`` steps ago or more, the ``count`` looked at longest ago (never: first;
        ties: the lowest id). Returns (track id, detection index) pairs."""
        b = self.box
        cand = sorted((self.looked.get(tid, -1), tid, i) for tid, i in self.detected.items()
                      if boxes[i, 3] < max_height and (self.facing_of(tid)[1] > b.look_std
                                                       or self.steps - self.looked.get(tid, -b.look_every)
                                                       >= b.look_every))
        return [(tid, i) for _, tid, i in cand[:count]]

    def look(self, looks: list[tuple[int, np.ndarray]]) -> None:
        """Close looks' keypoints (17, 3 each; frame pixels) of tracks' people, as (track id, keypoints) pairs: each
        track's facing filter takes their posterior (at the track's position) with weight ``box.look_weight``."""
        at = {st.id: st.position for st in self.tracker.states()}
        looks = [(tid, kp) for tid, kp in looks if tid in at and tid in self.facing]
        for tid, _ in looks:
            self.looked[tid] = self.steps
        if not looks:
            return
        kp = np.stack([np.asarray(k, dtype=float) for _, k in looks])
        q, ok = facing_posterior(self.geometry, kp, np.array([at[tid] for tid, _ in looks]), self.body)
        for (tid, _), qi, oi in zip(looks, q, ok, strict=True):
            if oi:
                self.facing[tid].update(qi, self.box.look_weight)

    def _filter_facing(self, states: list, dt: float) -> None:
        """Each track's facing filter: predicted by ``dt``, updated with its detection's posterior where it has
        one (payload)."""
        b = self.box
        for st in states:
            ft = self.facing.get(st.id)
            if ft is None:
                ft = self.facing[st.id] = FacingTrack(self.body, b.facing_turn_std, b.facing_floor)
            ft.predict(dt)
            if st.payload is not None and st.misses == 0 and st.payload[2] is not None:
                ft.update(st.payload[2], b.facing_weight)

    def body_height(self, foot_xy: np.ndarray, top_v: np.ndarray) -> np.ndarray:
        """Height (m) of a person standing at ``foot_xy`` (n, 2) whose box top is at image row ``top_v``."""
        lo = self.camera.world_to_image(np.column_stack([foot_xy, np.zeros(len(foot_xy))]))[:, 1]
        hi = self.camera.world_to_image(np.column_stack([foot_xy, np.ones(len(foot_xy))]))[:, 1]
        return (lo - top_v) / np.maximum(lo - hi, 1e-6)

    def step(self, boxes: np.ndarray, dt: float) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        """Boxes (n, >=4) ``x, y, w, h[, score]`` or people rows (``movenet.PEOPLE_COLUMNS``: with keypoints) ->
        list of (id, image box (4,), ground xy (2,), velocity (2,)); each track's facing: ``facing_of``."""
        boxes = np.asarray(boxes, dtype=float)
        boxes = boxes.reshape(-1, boxes.shape[-1] if boxes.ndim == 2 else 5)
        kp = split(boxes)[1] if len(boxes) else None
        if kp is not None:
            boxes = boxes[:, :5]
        feet = np.column_stack([boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3]])
        ground = self.camera.image_to_ground(feet) if len(boxes) else np.zeros((0, 2))
        heights = self.body_height(ground, boxes[:, 1]) if len(boxes) else np.zeros(0)
        b = self.box
        cov = None
        if b.pixel_noise > 0 and len(boxes):
            cov = ground_covariance(self.camera, feet, b.pixel_noise * boxes[:, 3])
            cov += np.eye(2) * self.tracker.params.meas_std ** 2
        self.cues = np.full(len(boxes), FEET, dtype=int)
        if b.head_ranging and len(boxes):
            h_img = self.camera.height * self.camera.scale
            xy, rcov, self.cues = range_boxes(self.geometry, boxes, h_img, self.ranging, kp, self.body)
            head = self.cues == HEAD
            ground = np.where(head[:, None], xy, ground)
            heights = np.where(head, np.nan, heights)  # the prior, not a measurement: no height update
            rcov += np.eye(2) * self.tracker.params.meas_std ** 2
            cov = np.where(head[:, None, None], rcov, rcov if cov is None else cov)
        post: list[np.ndarray | None] = [None] * len(boxes)
        if kp is not None and len(boxes):
            q, ok = facing_posterior(self.geometry, kp, ground, self.body)
            post = [q[i] if ok[i] else None for i in range(len(boxes))]
        # a head-ranged box is cut above the feet: it never stands in for the drawn box
        payloads = [(float(heights[i]), boxes[i, :4].copy() if self.cues[i] == FEET else None, post[i], i)
                    for i in range(len(boxes))]
        scores = boxes[:, 4] if boxes.shape[1] > 4 else None
        states = self.tracker.update(ground, dt=dt, payloads=payloads, meas_cov=cov, scores=scores)
        self.steps += 1
        self.detected = {st.id: st.payload[3] for st in states if st.payload is not None and st.misses == 0}
        self._filter_facing(states, dt)
        out = []
        alive = set()
        for st in states:
            alive.add(st.id)
            if st.payload is not None and np.isfinite(st.payload[0]):
                h_m = float(np.clip(st.payload[0], *b.height_range))
                old = self.heights.get(st.id)
                self.heights[st.id] = h_m if old is None else old + b.height_gain * (h_m - old)
            if st.misses > max(b.max_coast, b.max_coast_inside):
                continue
            h_m = self.heights.get(st.id, b.default_height)
            foot = self.camera.world_to_image(np.array([*st.position, 0.0]))
            head = self.camera.world_to_image(np.array([*st.position, h_m]))
            hpx = foot[1] - head[1]
            wpx = b.aspect * hpx
            cx = 0.5 * (foot[0] + head[0])
            box = np.array([cx - wpx / 2, head[1], wpx, hpx])
            if st.misses > b.max_coast:
                w_img, h_img = self.camera.width * self.camera.scale, self.camera.height * self.camera.scale
                inside = box[0] >= 0 and box[1] >= 0 and box[0] + box[2] <= w_img and box[1] + box[3] <= h_img
                if not (inside and st.hits >= 10):
                    continue
            if st.payload is not None and st.payload[1] is not None and b.det_weight > 0:
                box = (1 - b.det_weight) * box + b.det_weight * st.payload[1]
            out.append((st.id, box, st.position.copy(), st.velocity.copy()))
        live = {tr.id for tr in self.tracker.tracks}
        for k in list(self.heights):
            if k not in alive and k not in live:
                del self.heights[k]
        for d in (self.facing, self.looked):
            for k in list(d):
                if k not in live:
                    del d[k]
        return out


def ground_covariance(camera: TsaiCamera, feet: np.ndarray, sigma_px: np.ndarray) -> np.ndarray:
    """Ground covariance (n, 2, 2) in m^2 of foot points (n, 2) with isotropic pixel noise ``sigma_px`` (n,)."""
    eps = 0.5
    g0 = camera.image_to_ground(feet)
    jac = np.stack([(camera.image_to_ground(feet + [eps, 0]) - g0) / eps,
                    (camera.image_to_ground(feet + [0, eps]) - g0) / eps], axis=-1)  # (n, 2, 2)
    return jac @ jac.transpose(0, 2, 1) * (np.asarray(sigma_px, dtype=float) ** 2)[:, None, None]


def track_detections(dets: dict[int, np.ndarray], camera: TsaiCamera, dt: float,
                     params: TrackerParams | None = None, box: BoxParams | None = None,
                     ranging: RangingParams | None = None, body: BodyParams | None = None) -> np.ndarray:
    """Run ``GroundTracker`` over per-frame boxes or people rows (frames in increasing order; missing frames = no
    boxes).

    Returns (m, 11) rows ``frame, id, left, top, w, h, x_m, y_m, vx, vy, facing`` (facing: yaw in rad, NaN
    unknown; ``GroundTracker.facing_of``)."""
    gt = GroundTracker(camera, params, box, ranging, body)
    rows = []
    if not dets:
        return np.zeros((0, 11))
    for f in range(min(dets), max(dets) + 1):
        for tid, bb, xy, v in gt.step(dets.get(f, np.zeros((0, 5))), dt):
            rows.append((f, tid, *bb, *xy, *v, gt.facing_of(tid)[0]))
    return np.array(rows, dtype=float).reshape(-1, 11)
