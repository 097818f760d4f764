"""Tracking metrics: MOTA, IDF1, ID switches (motmetrics, IoU >= 0.5) and ground-plane position error.

The ground-plane error pairs each ground-truth box with the track motmetrics matched it to, projects the GT foot
point with the calibration and compares it with the track's ground position (columns 6-7 of a track row when
present, else the track box's projected foot point), in metres.
"""

from __future__ import annotations

import numpy as np

if not hasattr(np, "asfarray"):  # motmetrics 1.4 still calls np.asfarray, removed in NumPy 2
    np.asfarray = lambda a, dtype=float: np.asarray(a, dtype=dtype)  # type: ignore[attr-defined]

import motmetrics as mm  # noqa: E402

from .pets import foot_points  # noqa: E402
from .tsai import TsaiCamera  # noqa: E402


def _by_frame(rows: np.ndarray) -> dict[int, np.ndarray]:
    out: dict[int, list[np.ndarray]] = {}
    for r in rows:
        out.setdefault(int(r[0]), []).append(r)
    return {k: np.array(v) for k, v in out.items()}


def evaluate(tracks: np.ndarray, gt: np.ndarray, camera: TsaiCamera | None = None, start: int = 0,
             stop: int | None = None, iou: float = 0.5) -> dict[str, float]:
    """Compare track rows ``frame, id, left, top, w, h, ...`` with GT rows of the same layout (0-based frames).

    Frames ``start <= f < stop`` (stop None = last GT frame + 1). Returns MOTA, IDF1, ID switches, counts and,
    with a camera, the ground-plane error median / 90th percentile (m) over matched pairs."""
    tracks = np.asarray(tracks, dtype=float).reshape(-1, tracks.shape[-1] if len(tracks) else 6)
    gt = np.asarray(gt, dtype=float)
    stop = int(gt[:, 0].max()) + 1 if stop is None else stop
    acc = mm.MOTAccumulator(auto_id=False)
    tb, gb = _by_frame(tracks), _by_frame(gt)
    for f in range(start, stop):
        g = gb.get(f, np.zeros((0, 7)))
        t = tb.get(f, np.zeros((0, 6)))
        dist = mm.distances.iou_matrix(g[:, 2:6], t[:, 2:6], max_iou=1 - iou) if len(g) and len(t) \
            else np.zeros((len(g), len(t)))
        acc.update(g[:, 1].astype(int).tolist(), t[:, 1].astype(int).tolist(), dist, frameid=f)
    errors = []
    if camera is not None:
        ev = acc.mot_events
        ev = ev[ev.Type.isin(["MATCH", "SWITCH"])]
        for (f, _), oid, hid in zip(ev.index, ev.OId.values, ev.HId.values, strict=True):
            g, t = gb[f], tb[f]
            gxy = camera.image_to_ground(foot_points(g[g[:, 1] == oid][0, 2:6]))
            trow = t[t[:, 1] == hid][0]
            txy = trow[6:8] if len(trow) >= 8 else camera.image_to_ground(foot_points(trow[2:6]))
            errors.append(float(np.hypot(*(gxy - txy))))
    mh = mm.metrics.create()
    summ = mh.compute(acc, metrics=["mota", "motp", "idf1", "num_switches", "num_false_positives",
                                    "num_misses", "num_objects", "precision", "recall", "mostly_tracked",
                                    "num_unique_objects"], name="x")
    res = {k: float(summ[k].iloc[0]) for k in summ.columns}
    res["motp_iou"] = 1.0 - res.pop("motp") if np.isfinite(res["motp"]) else float("nan")
    res["frames"] = [start, stop - 1]
    if camera is not None:
        d = np.array(errors)
        res["ground_err_median_m"] = float(np.median(d)) if len(d) else float("nan")
        res["ground_err_p90_m"] = float(np.percentile(d, 90)) if len(d) else float("nan")
        res["ground_err_pairs"] = int(len(d))
    return res


def to_markdown(results: dict[str, dict[str, float]], title: str = "Tracking results") -> str:
    """A table with one row per named result (``{"frames 400-794": {...}}``)."""
    cols = ["mota", "idf1", "num_switches", "precision", "recall", "num_false_positives", "num_misses",
            "ground_err_median_m", "ground_err_p90_m"]
    lines = [f"# {title}", "", "| range | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name, r in results.items():
        cells = []
        for c in cols:
            v = r.get(c, float("nan"))
            cells.append(f"{v:.0f}" if c.startswith("num_") else f"{v:.3f}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
