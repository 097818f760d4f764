"""Threshold selection on a frame range by coordinate descent over small grids (MOTA + IDF1 as the score).

Works on cached detector output (``pipeline.detect_raw`` windows for HOG, ``cache_raw`` boxes for the learned
detector), so one detector pass serves every trial. Only frames inside the given range are read, which is how the
benchmark keeps frames 400-794 unseen while choosing thresholds; ``extra`` caches (the same frames with the feet
hidden) add their score to the objective.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

import numpy as np

from ...errors import UserError
from ..datasets.scoring import evaluate
from ..datasets.tsai import TsaiCamera
from ..detection.detectors import HogParams
from ..detection.learned import SsdDetector, SsdParams, select_ssd
from ..detection.movenet import network
from ..detection.ranging import RangingParams
from .pipeline import BoxParams, select, track_detections
from .tracker import TrackerParams

ALL_SCALES = (0.8, 1.0, 1.2, 1.45, 1.75, 2.1)  # the scales cached by the benchmark's HOG pass

GRID: dict[str, list[Any]] = {
    "hog.hit_threshold": [0.0, 0.2, 0.4, 0.6, 0.8, 1.0],
    "trk.birth_score": [0.6, 0.8, 1.0, 1.2, 1.5],
    "hog.fg_min": [0.0, 0.1, 0.2, 0.3, 0.45],
    "hog.nms_iou": [0.2, 0.3, 0.45],
    "hog.scales": [ALL_SCALES, ALL_SCALES[1:5], ALL_SCALES[:5], ALL_SCALES[1:]],
    "hog.min_height": [0.0, 50.0, 60.0],
    "trk.meas_std": [0.02, 0.05, 0.1, 0.15],
    "box.pixel_noise": [0.03, 0.05, 0.07, 0.1],
    "trk.accel_std": [0.5, 1.0, 1.5, 2.5],
    "trk.gate": [6.0, 9.2, 13.8, 20.0, 30.0],
    "trk.birth_hits": [2, 3, 4, 5, 6],
    "trk.max_misses": [5, 10, 15, 25],
    "trk.tentative_misses": [1, 2],
    "trk.min_new_dist": [0.0, 0.5, 0.8, 1.2],
    "box.aspect": [0.36, 0.4, 0.44, 0.48],
    "box.max_coast": [0, 1, 2, 3, 5],
    "box.height_gain": [0.1, 0.2, 0.4],
    "box.det_weight": [0.0, 0.25, 0.5],
    "box.max_coast_inside": [0, 5, 8],
}

# the same search for the learned detector (``learned.SsdDetector``): its score and box thresholds instead of HOG's,
# and the measurement noise of each ranging cue (feet: ``box.pixel_noise``; head: ``rng.*``)
SSD_GRID: dict[str, list[Any]] = {
    "ssd.score_threshold": [0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4],
    "trk.birth_score": [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8],
    "ssd.nms_iou": [0.3, 0.45, 0.6],
    "ssd.min_height": [0.0, 40.0, 55.0],
    # HOG's tracker and box grids, less its birth margins (SVM margins 0.8-1.5: a network's scores are 0-1; merged
    # in, they replaced the list above and no track was ever born from MoveNet's 0.1-0.45 scores)
    **{k: v for k, v in GRID.items() if k.startswith(("trk.", "box.")) and k != "trk.birth_score"},
    "rng.pixel_noise": [0.03, 0.05, 0.1, 0.15, 0.2],
    "rng.height_std": [0.05, 0.08, 0.12],
    "rng.width_rel_std": [0.15, 0.25, 0.4],
    "rng.min_body_height": [1.3, 1.4, 1.5, 1.6],  # which boxes count as whole (feet) or cut (head)
    "rng.max_aspect": [float("inf"), 0.6, 0.5, 0.45],
}
DETECTORS = ("hog", "ssd", "movenet")
LEARNED = ("ssd", "movenet")  # networks whose boxes ``ssd`` params select (``learned.select_ssd``)


@dataclasses.dataclass(frozen=True)
class PipelineParams:
    """Every threshold of the PETS pipeline, grouped by component. The defaults are the values
    tools/bench_tracking.py chose on PETS S2L1 frames 0-399 (coordinate descent from ``UNTUNED``, HOG stride 4
    selected over 8 on the 0-399 score). For 320x240 deploy frames use ``hog.win_stride = 8`` (22 ms vs 65 ms
    per frame on one core)."""

    hog: HogParams = HogParams(scales=(0.8, 1.0, 1.2, 1.45, 1.75), hit_threshold=0.8, win_stride=4,
                               shrink_x=0.235, shrink_top=0.115, shrink_bottom=0.14, nms_iou=0.2, fg_min=0.0)
    trk: TrackerParams = TrackerParams(accel_std=1.5, meas_std=0.05, gate=13.8, birth_hits=2, max_misses=10,
                                       tentative_misses=2, min_new_dist=0.0, birth_score=1.2)
    box: BoxParams = BoxParams(height_gain=0.1, aspect=0.48, max_coast=1, max_coast_inside=8, det_weight=0.5,
                               pixel_noise=0.05)
    detector: str = "hog"  # "hog" (``hog`` params), "ssd" or "movenet" (learned networks, ``ssd`` params)
    ssd: SsdParams = SsdParams()  # a learned network's input size and box selection (SSD's or MoveNet's boxes)
    rng: RangingParams = RangingParams()  # head-and-shoulders ranging (``box.head_ranging``): priors, head-cue noise

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise UserError(f"detector = {self.detector!r}: expected one of {list(DETECTORS)}")
        if self.detector == "movenet" and any(v % 32 for v in self.ssd.input_size):
            raise UserError(f"ssd.input_size = {self.ssd.input_size!r}: MoveNet takes multiples of 32 (w, h)")

    def with_value(self, key: str, value: Any) -> PipelineParams:
        part, name = key.split(".")
        return dataclasses.replace(self, **{part: dataclasses.replace(getattr(self, part), **{name: value})})

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {k: dataclasses.asdict(getattr(self, k)) for k in ("hog", "trk", "box", "ssd", "rng")}
        out["detector"] = self.detector
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PipelineParams:
        """Inverse of ``to_dict``; ``detector``, ``ssd`` and ``rng`` may be absent (HOG-only files)."""
        def fix(d: dict[str, Any]) -> dict[str, Any]:
            return {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(hog=HogParams(**fix(data["hog"])), trk=TrackerParams(**fix(data["trk"])),
                   box=BoxParams(**fix(data["box"])), detector=data.get("detector", "hog"),
                   ssd=SsdParams(**fix(data.get("ssd", {}))), rng=RangingParams(**fix(data.get("rng", {}))))

    @property
    def grid(self) -> dict[str, list[Any]]:
        """The threshold search's grid for this detector."""
        return SSD_GRID if self.detector in LEARNED else GRID


# Where the search starts: box shrink measured on frames 0-399 (median HOG window -> GT box offsets), the rest
# picked by hand from a few runs on frames 0-399.
UNTUNED = PipelineParams(
    hog=HogParams(scales=ALL_SCALES, hit_threshold=0.6, shrink_x=0.235, shrink_top=0.115, shrink_bottom=0.14,
                  fg_min=0.2),
    trk=TrackerParams(meas_std=0.05),
    box=BoxParams(pixel_noise=0.06))


# the learned detector's pipeline: thresholds chosen on frames 0-399 by ``tools/bench_tracking.py --tune --detector ssd
# --input-size 400x300`` (box offsets measured there, then coordinate descent over ``SSD_GRID`` from the previous
# values, MOTA + IDF1 with the feet visible and hidden; 0-399 score 1.37 -> 2.09); see docs/tracking.md
SSD_UNTUNED = PipelineParams(detector="ssd", ssd=SsdParams(score_threshold=0.25),
                             trk=dataclasses.replace(UNTUNED.trk, birth_score=0.4),
                             box=dataclasses.replace(UNTUNED.box, head_ranging=True),
                             rng=RangingParams(pixel_noise=UNTUNED.box.pixel_noise))
SSD_DEFAULT = PipelineParams(
    detector="ssd", ssd=SsdParams(input_size=(400, 300), score_threshold=0.05, nms_iou=0.3, min_height=40.0,
                                  shrink_x=0.085, shift_x=0.107, shrink_top=-0.017, shrink_bottom=0.036),
    trk=TrackerParams(accel_std=1.0, meas_std=0.15, gate=13.8, birth_hits=2, max_misses=15, tentative_misses=2,
                      min_new_dist=0.0, birth_score=0.6),
    box=BoxParams(height_gain=0.2, aspect=0.48, max_coast=0, max_coast_inside=8, det_weight=0.5, pixel_noise=0.1,
                  head_ranging=True),
    rng=RangingParams(min_body_height=1.6, max_aspect=0.5, pixel_noise=0.1))


# MoveNet (``movenet.MoveNetDetector``): the SSD's chosen tracker and ranging as a start, its own input (the 4:3
# frame at half size, a multiple of 32) and score; its box offsets are measured by ``--tune`` on frames 0-399
MOVENET_UNTUNED = dataclasses.replace(
    SSD_DEFAULT, detector="movenet", trk=dataclasses.replace(SSD_DEFAULT.trk, birth_score=0.2),
    ssd=SsdParams(input_size=(384, 288), score_threshold=0.05, raw_threshold=0.02, nms_iou=0.45))
#   (its person scores on PETS are 0.14-0.43, 10th-99th percentile: the SSD's birth score, 0.6, bore no track)
# chosen on frames 0-399 by ``tools/bench_tracking.py --tune --detector movenet --rounds 1`` (box offsets measured
# there, then one round of coordinate descent over ``SSD_GRID`` from the previous values, people cut above the feet
# ranged from their keypoints; 0-399 score 2.31 -> 2.44); docs/tracking.md
MOVENET_DEFAULT = PipelineParams(
    detector="movenet",
    ssd=SsdParams(input_size=(384, 288), score_threshold=0.05, raw_threshold=0.02, nms_iou=0.3, shrink_x=0.048,
                  shift_x=0.018, shrink_top=0.013, shrink_bottom=0.004),
    trk=TrackerParams(accel_std=1.0, meas_std=0.02, gate=13.8, birth_hits=2, max_misses=25, tentative_misses=2,
                      min_new_dist=0.0, birth_score=0.2),
    box=BoxParams(height_gain=0.4, aspect=0.48, max_coast=0, max_coast_inside=5, det_weight=0.5, pixel_noise=0.07,
                  head_ranging=True),
    rng=RangingParams(min_body_height=1.6, max_aspect=0.6, pixel_noise=0.2, height_std=0.05, width_rel_std=0.15))


def default_params(detector: str) -> PipelineParams:
    """The built-in (tuned) pipeline for ``detector`` ("hog", "ssd" or "movenet")."""
    if detector not in DETECTORS:
        raise UserError(f"detector {detector!r}: expected one of {list(DETECTORS)}")
    return {"ssd": SSD_DEFAULT, "movenet": MOVENET_DEFAULT}.get(detector, PipelineParams())


def keep_scales(raw: np.ndarray, scales: tuple[float, ...]) -> np.ndarray:
    """Rows of ``detect_raw`` output whose window came from one of ``scales`` (window width = 64 / scale)."""
    s = 64.0 / raw[:, 2]
    ok = np.zeros(len(raw), dtype=bool)
    for sc in scales:
        ok |= np.isclose(s, sc, rtol=1e-3)
    return raw[ok]


def select_cached(raw: np.ndarray, params: PipelineParams) -> np.ndarray:
    """One frame's cached raw rows (``detect_raw`` windows or ``SsdDetector.raw`` boxes) -> detections."""
    if params.detector in LEARNED:
        return select_ssd(raw, params.ssd)
    return select(keep_scales(raw, params.hog.scales), params.hog)


def run_pipeline(raw: dict[int, np.ndarray], camera: TsaiCamera, params: PipelineParams, dt: float,
                 start: int, stop: int) -> np.ndarray:
    """Track rows (``track_detections`` layout) for frames ``start <= f < stop`` from cached detections."""
    dets = {f: select_cached(raw[f], params) for f in range(start, stop) if f in raw}
    return track_detections(dets, camera, dt, params.trk, params.box, params.rng)


def score(res: dict[str, float]) -> float:
    return float(res["mota"] + res["idf1"])


def tune(raw: dict[int, np.ndarray], gt: np.ndarray, camera: TsaiCamera, dt: float, start: int, stop: int,
         init: PipelineParams | None = None, rounds: int = 2, grid: dict[str, list[Any]] | None = None,
         extra: tuple[dict[int, np.ndarray], ...] = ()) -> tuple[PipelineParams, dict[str, float], list[dict]]:
    """Coordinate descent on frames ``start <= f < stop``; returns the best params, their metrics on ``raw``, the log.

    ``extra``: cached detections of other versions of the same frames (e.g. the feet-hidden ones); the score is
    then the sum of MOTA + IDF1 over ``raw`` and each of them."""
    def trial(p: PipelineParams) -> tuple[float, dict[str, float], list[float]]:
        res = evaluate(run_pipeline(raw, camera, p, dt, start, stop), gt, camera, start, stop)
        more = [score(evaluate(run_pipeline(r, camera, p, dt, start, stop), gt, camera, start, stop)) for r in extra]
        return score(res) + sum(more), res, [score(res), *more]

    best = init or PipelineParams()
    best_s, best_res, parts = trial(best)
    log = [{"key": "init", "value": None, "score": best_s, "parts": parts}]
    for _ in range(rounds):
        improved = False
        for key, values in (grid or best.grid).items():
            for v in values:
                cand = best.with_value(key, v)
                if cand == best:
                    continue
                s, res, parts = trial(cand)
                log.append({"key": key, "value": v, "score": s, "parts": parts})
                if s > best_s + 1e-6:
                    best, best_s, best_res, improved = cand, s, res, True
        if not improved:
            break
    return best, best_res, log


def cache_raw(frames: Iterable[tuple[int, np.ndarray]], params: PipelineParams) -> dict[int, np.ndarray]:
    """The learned network's raw boxes (every box above ``ssd.raw_threshold``) for each ``(index, BGR frame)``: the
    cache the search selects from (``select_cached``), so one network pass serves every trial."""
    if params.detector not in LEARNED:
        raise UserError(f"cache_raw: detector {params.detector!r}; HOG windows are cached by pipeline.detect_raw")
    raw = learned_raw(params)
    return {i: raw(f) for i, f in frames}


def learned_raw(params: PipelineParams) -> Any:
    """``frame -> (n, 5)`` raw boxes of the learned network ``params.detector`` at ``ssd.input_size``."""
    if params.detector == "movenet":
        return network(params.ssd)
    return SsdDetector(params.ssd).raw
