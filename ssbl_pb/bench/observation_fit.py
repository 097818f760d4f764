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
- ``min_visible``: the share of the torso inside the image (nothing in front) at which the share detected falls to
  half that in plain sight (deploy drops MoveNet boxes cut by the image's side; interpolated between bins);
- ``hidden_fraction``: likewise, the share hidden behind nearer members (the whole torso in the image);
- ``facing_std_deg``, ``facing_back_std_deg``: the robust std of the facing error (within 90 deg) of members whose
  front is toward the robot (within ``facing_front_deg``) and of the others; ``facing_flip_prob``: the share more
  than 90 deg off.

Reported, not modelled: the share of member-ticks tracked twice and false tracks per tick.
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
    """Where the detected share crosses ``floor``, between the middles of the two counted bins either side of it
    (linearly): with ``rising`` (more is better: the image share) going down from the top bin, else (the hidden
    share) going up from the first. With no bin below ``floor``, the end of the range; with the first one below,
    its edge."""
    counted = [b for b in bins if b["n"] >= MIN_TICKS]
    if rising:
        counted = counted[::-1]
    for k, b in enumerate(counted):
        if b["seen_rate"] >= floor:
            continue
        if k == 0:
            return float(b["hi"] if rising else b["lo"])
        a = counted[k - 1]
        mid_a, mid_b = 0.5 * (a["lo"] + a["hi"]), 0.5 * (b["lo"] + b["hi"])
        x = mid_a + (a["seen_rate"] - floor) / (a["seen_rate"] - b["seen_rate"]) * (mid_b - mid_a)
        return float(min(max(x, 0.0), 1.0))
    return 0.0 if rising else 1.0


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
    flipped = np.abs(facing_err[has_facing]) > 90.0
    unflipped = has_facing & (np.abs(np.nan_to_num(facing_err, nan=180.0)) <= 90.0)  # the flips are their own field
    fields = {
        "detector": base.detector, "laser_reach_m": reach, "laser_std_m": round(robust_std(range_err[near]), 3),
        "range_std_m": 0.0,
        "range_std_per_m": round(robust_std(range_err[far] / rng[far]), 3),
        "bearing_std_deg": round(robust_std(bearing_err[detected]), 2),
        "miss_prob": round(miss, 3), "min_visible": round(threshold(image_bins, floor, rising=True), 2),
        "hidden_fraction": round(threshold(hidden_bins, floor, rising=False), 2),
        "facing_std_deg": round(robust_std(facing_err[unflipped & front]), 1),
        "facing_front_deg": base.facing_front_deg,
        "facing_back_std_deg": round(robust_std(facing_err[unflipped & ~front]), 1),
        "facing_flip_prob": round(float(flipped.mean()), 3) if len(flipped) else 0.0,
    }
    evidence = {
        "member_ticks": len(seen), "detected": int(detected.sum()), "plain_sight": int(plain.sum()),
        "range_by_distance": by_distance, "range_bias_m": float(np.median(range_err[detected]))
        if detected.any() else None, "seen_by_image_share": image_bins, "seen_by_hidden_share": hidden_bins,
        "facing_ticks": {"front": int((has_facing & front).sum()), "back": int((has_facing & ~front).sum())},
        "facing_known": float(has_facing.sum() / detected.sum()) if detected.any() else None,
        # not modelled (the model's detections are one per person, nothing else): deploy's duplicates and false
        # tracks, per member-tick and per tick
        "duplicated": float(np.mean(np.asarray(s.tracks) > 1)) if s.tracks else None,
        "false_tracks_per_tick": float(np.mean(s.false_tracks)) if s.false_tracks else None,
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
    out.append("")
    out.append(f"{e['detected']} detected of {e['member_ticks']} member-ticks ({e['plain_sight']} in plain sight); "
               f"median range error {bias}; facing known on {e['facing_known'] or 0:.0%} of detected member-ticks; "
               f"not modelled: {e['duplicated'] or 0:.1%} of member-ticks tracked twice, "
               f"{e['false_tracks_per_tick'] or 0:.3f} false tracks a tick.")
    return "\n".join(out) + "\n"


def plot(result: dict[str, Any], path: Any, title: str = "") -> Any:
    """The figure: the range error's robust std per distance bin with the fitted model, and the share detected
    against the torso's share in the image and the share hidden, with the fitted thresholds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f, e = result["fields"], result["evidence"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    bins = e["range_by_distance"]
    mid = [0.5 * (x["lo"] + (x["hi"] if x["hi"] is not None else x["lo"] + 2.0)) for x in bins]
    a.plot(mid, [x["std_m"] for x in bins], "o", label="measured (robust std per bin)")
    r = np.linspace(0.5, 6.0, 111)
    model = np.where(r < f["laser_reach_m"], f["laser_std_m"], f["range_std_m"] + f["range_std_per_m"] * r)
    a.plot(r, model, "-", label="model")
    a.set_xlabel("true distance from the robot (m)")
    a.set_ylabel("range error std (m)")
    a.set_title("range noise of detected members")
    a.legend(fontsize=7)
    a.grid(alpha=0.3)
    for key, label, edge, colour in (("seen_by_image_share", "torso share in the image", f["min_visible"], "C0"),
                                     ("seen_by_hidden_share", "torso share hidden", f["hidden_fraction"], "C1")):
        rows = [x for x in e[key] if x["n"] >= MIN_TICKS]
        b.plot([min(0.5 * (x["lo"] + x["hi"]), 1.0) for x in rows], [x["seen_rate"] for x in rows], "o-",
               color=colour, label=label)
        b.axvline(edge, color=colour, ls=":", alpha=0.8)
    b.set_xlabel("share of the torso")
    b.set_ylabel("share detected")
    b.set_ylim(-0.02, 1.05)
    b.set_title(f"share detected (dotted: the model's thresholds; {f['miss_prob']:.0%} missed in plain sight)",
                fontsize=9)
    b.legend(fontsize=7)
    b.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
