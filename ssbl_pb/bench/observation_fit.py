"""The observation model's numbers (``perception.groups.observation_model.PerceptionParams``) measured from deploy
runs against the virtual Pepper's ground truth (``perception_errors.Samples``, pooled over runs).

What is measured is deploy's tracks, not its raw detections: the tracker smooths position and the facing filter
smooths facing, so the noise fitted here is what the policy sees through the tracker, as the colour chain's was
(docs/benchmarks.md, "The robot's own view in training"). Each number, from member-ticks whose assigned track was
detected in that frame unless said otherwise:

- ``laser_std_m``: the robust std (1.4826 x the median absolute deviation) of the range error within the lasers'
  reach (``laser_reach_m``, the model's); ``range_std_per_m``: that of the range error over the range beyond it
  (keypoint ranges err in proportion to the range), ``range_std_m`` 0; ``range_by_distance`` and ``range_bias_m``
  (reported, not modelled): per distance bin and overall, the robust std and the median range error;
- ``bearing_std_deg``: the robust std of the bearing error;
- ``miss_prob``: of the member-ticks in plain sight (the whole torso in the image, nothing in front of it), the
  share not detected;
- ``min_visible``: the smallest share of the torso inside the image from which on the share detected (nothing in
  front) stays at least half that in plain sight (deploy drops MoveNet boxes cut by the image's side);
- ``hidden_fraction``: likewise, the largest share hidden behind nearer members up to which it stays so;
- ``facing_std_deg``, ``facing_back_std_deg``: the robust std of the facing error of members whose front is toward
  the robot (within ``facing_front_deg``) and of the others; ``facing_flipped`` (reported): the share more than
  90 deg off.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..perception.groups.observation_model import PerceptionParams
from .perception_errors import DISTANCE_BINS, Samples

ROBUST = 1.4826  # x the median absolute deviation: a Gaussian's std
IMAGE_BINS = (0.0, 0.2, 0.4, 0.6, 0.8, 0.95, 1.0, 1.01)  # share of the torso inside the image
HIDDEN_BINS = (0.0, 1e-9, 0.25, 0.5, 0.75, 0.9, 1.01)  # share hidden behind nearer members (first bin: none)
MIN_TICKS = 30  # member-ticks a bin needs to count


def robust_std(x: Any) -> float:
    """1.4826 x the median absolute deviation of the finite values (NaN when there are none)."""
    a = np.asarray(x, dtype=float)
    a = a[np.isfinite(a)]
    return float(ROBUST * np.median(np.abs(a - np.median(a)))) if len(a) else math.nan


def seen_by_bin(share: np.ndarray, seen: np.ndarray, edges: tuple[float, ...]) -> list[dict[str, Any]]:
    """Per bin of ``share`` (lower edge inclusive): member-ticks and the share of them detected."""
    out = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        here = (share >= lo) & (share < hi)
        out.append({"lo": lo, "hi": hi, "n": int(here.sum()),
                    "seen_rate": float(seen[here].mean()) if here.any() else None})
    return out


def threshold(bins: list[dict[str, Any]], floor: float, rising: bool) -> float:
    """Where the detected share crosses ``floor``: with ``rising`` (more is better: the image share) the lower edge
    of the lowest bin from which every counted bin on is at least ``floor``; else (the hidden share) the upper edge
    of the last counted bin before the first one below it (0 when the first is)."""
    counted = [b for b in bins if b["n"] >= MIN_TICKS]
    if rising:
        edge = counted[-1]["lo"] if counted else 1.0
        for b in reversed(counted):
            if b["seen_rate"] < floor:
                break
            edge = b["lo"]
        return float(min(edge, 1.0))
    edge = 0.0
    for b in counted:
        if b["seen_rate"] < floor:
            break
        edge = b["hi"]
    return float(min(edge, 1.0))


def fit(s: Samples, base: PerceptionParams | None = None) -> dict[str, Any]:
    """The observation model's fields measured from pooled samples (``fields``: ``PerceptionParams`` keywords;
    ``base``'s lasers' reach and front angle, default the MoveNet chain's), and what they rest on (``evidence``)."""
    base = base or PerceptionParams()
    seen, remembered = np.asarray(s.seen, dtype=bool), np.asarray(s.remembered, dtype=bool)
    rng = np.asarray(s.range_m, dtype=float)
    range_err, bearing_err = np.asarray(s.range_err, dtype=float), np.asarray(s.bearing_err, dtype=float)
    facing_err, front = np.asarray(s.facing_err, dtype=float), np.asarray(s.front, dtype=bool)
    hidden, in_image = np.asarray(s.hidden, dtype=float), np.asarray(s.in_image, dtype=float)
    detected = seen & ~remembered & np.isfinite(range_err)
    reach = base.laser_reach_m
    by_distance = []
    for lo, hi in zip(DISTANCE_BINS[:-1], DISTANCE_BINS[1:], strict=True):
        here = detected & (rng >= lo) & (rng < hi)
        if here.sum() >= MIN_TICKS:
            by_distance.append({"lo": lo, "hi": None if math.isinf(hi) else hi, "n": int(here.sum()),
                                "std_m": robust_std(range_err[here]), "bias_m": float(np.median(range_err[here]))})
    near, far = detected & (rng < reach), detected & (rng >= reach)
    plain = (in_image >= 1.0) & (hidden <= 0.0)
    miss = float(1.0 - seen[plain].mean()) if plain.any() else math.nan
    floor = 0.5 * (1.0 - miss) if math.isfinite(miss) else 0.5
    image_bins = seen_by_bin(in_image[hidden <= 0.0], seen[hidden <= 0.0], IMAGE_BINS)
    hidden_bins = seen_by_bin(hidden[in_image >= 1.0], seen[in_image >= 1.0], HIDDEN_BINS)
    has_facing = detected & np.isfinite(facing_err)
    fields = {
        "detector": base.detector, "laser_reach_m": reach, "laser_std_m": round(robust_std(range_err[near]), 3),
        "range_std_m": 0.0,
        "range_std_per_m": round(robust_std(range_err[far] / rng[far]), 3),
        "bearing_std_deg": round(robust_std(bearing_err[detected]), 2),
        "miss_prob": round(miss, 3), "min_visible": round(threshold(image_bins, floor, rising=True), 2),
        "hidden_fraction": round(threshold(hidden_bins, floor, rising=False), 2),
        "facing_std_deg": round(robust_std(facing_err[has_facing & front]), 1),
        "facing_front_deg": base.facing_front_deg,
        "facing_back_std_deg": round(robust_std(facing_err[has_facing & ~front]), 1),
    }
    flipped = np.abs(facing_err[has_facing]) > 90.0
    evidence = {
        "member_ticks": len(seen), "detected": int(detected.sum()), "plain_sight": int(plain.sum()),
        "range_by_distance": by_distance, "range_bias_m": float(np.median(range_err[detected]))
        if detected.any() else None, "seen_by_image_share": image_bins, "seen_by_hidden_share": hidden_bins,
        "facing_ticks": {"front": int((has_facing & front).sum()), "back": int((has_facing & ~front).sum())},
        "facing_known": float(has_facing.sum() / detected.sum()) if detected.any() else None,
        "facing_flipped": float(flipped.mean()) if len(flipped) else None,
        "facing_abs_median_deg": {k: float(np.median(np.abs(facing_err[has_facing & m]))) if (has_facing & m).any()
                                  else None for k, m in (("front", front), ("back", ~front))},
    }
    return {"fields": fields, "evidence": evidence}


def markdown(result: dict[str, Any], current: dict[str, Any]) -> str:
    """A table: each fitted field beside ``current`` (the model's values now)."""
    out = ["| field | measured | model now |", "|---|---|---|"]
    for k, v in result["fields"].items():
        out.append(f"| `{k}` | {v if isinstance(v, str) else format(v, 'g')} | {current.get(k, '-')} |")
    e = result["evidence"]
    bias = "-" if e["range_bias_m"] is None else f"{e['range_bias_m']:+.3f} m"
    flipped = "-" if e["facing_flipped"] is None else f"{e['facing_flipped']:.1%}"
    out.append("")
    out.append(f"{e['detected']} detected of {e['member_ticks']} member-ticks ({e['plain_sight']} in plain sight); "
               f"median range error {bias}; facing known on {e['facing_known'] or 0:.0%} of detected member-ticks, "
               f"{flipped} of them more than 90 deg off.")
    return "\n".join(out) + "\n"
