"""Summaries, files and plots of evaluation runs: per-episode CSV, summary JSON with 95 % CIs, paths plot."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..agents.metrics import METRICS
from ..files import write_json, write_text

__all__ = ["mean_ci", "proportion_ci", "wilson_interval", "summarize", "write_csv", "write_json", "plot_paths"]

SUMMARY_ALIASES = {"success_rate": "success", "collision_rate": "collision", "violation_rate": "violation",
                   "obstacle_collision_rate": "obstacle_collision", "mean_return": "return"}


def mean_ci(values: Sequence[float], level: float = 0.95) -> dict[str, float]:
    """Mean and Student-t confidence interval of the finite values (NaNs, e.g. no success, are skipped)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    n = len(v)
    if n == 0:
        return {"mean": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"), "n": 0}
    m = float(v.mean())
    if n == 1 or np.all(v == v[0]):
        return {"mean": m, "ci_low": m, "ci_high": m, "n": n}
    from scipy import stats  # heavy: scipy.stats (~0.5 s), kept out of the evaluation's import

    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * v.std(ddof=1) / math.sqrt(n))
    return {"mean": m, "ci_low": m - half, "ci_high": m + half, "n": n}


def wilson_interval(p: float, n: float, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion ``p`` seen over ``n`` trials (``n`` may be an effective, fractional
    count); unlike mean +- t * SE it stays inside [0, 1] and is not empty at 0 or 1 successes."""
    from scipy import stats  # heavy: as above

    z = float(stats.norm.ppf(0.5 + level / 2))
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(max(p * (1 - p), 0.0) / n + z * z / (4 * n * n)) / denom
    return (0.0 if p <= 0 else max(0.0, centre - half)), (1.0 if p >= 1 else min(1.0, centre + half))


def proportion_ci(values: Sequence[float], per_value: int = 1, level: float = 0.95) -> dict[str, float]:
    """Mean and Wilson interval of a proportion: ``values`` are 0/1 outcomes (``per_value`` 1, e.g. success per
    episode) or rates each over ``per_value`` outcomes (a sweep's seeds, each evaluated on that many episodes).
    Rates count as their pooled outcomes, or as fewer where the seeds disagree more than binomial noise
    explains: as many as make the interval's spread the Student-t one over the seeds."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    n = len(v)
    if n == 0:
        return {"mean": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"), "n": 0}
    p = float(np.clip(v.mean(), 0.0, 1.0))
    count = float(n * max(1, per_value))
    if per_value > 1 and n > 1 and v.var(ddof=1) > 0 and 0 < p < 1:
        from scipy import stats  # heavy: as above

        t, z = stats.t.ppf(0.5 + level / 2, n - 1), stats.norm.ppf(0.5 + level / 2)
        count = min(count, float(p * (1 - p) / (v.var(ddof=1) / n) * (z / t) ** 2))
    low, high = wilson_interval(p, count, level)
    return {"mean": p, "ci_low": low, "ci_high": high, "n": n}


def summarize(rows: list[dict[str, float]], extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """Mean and 95 % CI of every metric (Wilson for the 0/1 ones: success, collision, ...; Student t for the
    others); the headline keys (``success_rate``, ...) hold the means."""
    keys = [k for k in rows[0] if k != "seed"]
    per = {k: (proportion_ci if METRICS.get(k, ("",))[0] == "0/1" else mean_ci)([r[k] for r in rows]) for k in keys}
    out: dict[str, Any] = dict(extra or {})
    out["episodes"] = len(rows)
    for alias, key in SUMMARY_ALIASES.items():
        out[alias] = per[key]["mean"]
    for key in ("personal_zone_time_s", "human_displacement_m", "mean_jerk", "arrival_speed",
                "outside_fov_time_s", "time_to_success_s", "path_length_m", "min_obstacle_clearance_m",
                "shield_intervention_rate"):
        out[key] = per[key]["mean"]
    rules = {k[len("shield_"):-len("_rate")]: per[k]["mean"] for k in keys
             if k.startswith("shield_") and k.endswith("_rate") and k != "shield_intervention_rate"}
    if rules:  # each shield rule's share of the steps the policy drove (``agents.rollout``)
        out["shield_rules"] = rules
    out["metrics"] = per
    return out


def write_csv(path: Path, rows: list[dict[str, float]]) -> None:
    """One row per episode, columns in the rows' key order."""
    import io

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    write_text(path, buf.getvalue())


def box_corners(boxes: np.ndarray) -> np.ndarray:
    """Corners (B, 4, 2) of boxes (B, 5) ``(cx, cy, size_x, size_y, yaw)``, for drawing."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 5)
    local = np.array([[0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5], [0.5, -0.5]])[None] * b[:, None, 2:4]
    c, s = np.cos(b[:, 4])[:, None], np.sin(b[:, 4])[:, None]
    return np.stack([c * local[..., 0] - s * local[..., 1], s * local[..., 0] + c * local[..., 1]], -1) + b[:, None, :2]


def view_bounds(robot: np.ndarray, members: np.ndarray, slot: Sequence[float], centre: Sequence[float],
                radius: float, margin: float = 1.0) -> tuple[tuple[float, float], tuple[float, float]]:
    """Square (x, y) limits of a path panel: the robot's path, the members', the place and the o-space circle,
    ``margin`` metres round them."""
    c, r = np.asarray(centre, dtype=float), float(radius)
    pts = np.vstack([np.asarray(robot, float).reshape(-1, 2), np.asarray(members, float).reshape(-1, 2),
                     np.asarray(slot, float).reshape(1, 2), c - r, c + r])
    lo, hi = pts.min(0) - margin, pts.max(0) + margin
    mid, half = (lo + hi) / 2, float(max(hi - lo)) / 2
    return (mid[0] - half, mid[0] + half), (mid[1] - half, mid[1] + half)


def plot_paths(path: Path, trajectories: list[list[dict[str, Any]]], titles: list[str], room: tuple[float, float],
               cols: int = 3, personal: float = 1.2, human_radius: float = 0.28) -> None:
    """Top-down paths of the robot (with speed colouring) and the members, one panel per episode, with the room's
    walls and obstacles where the trajectory's first state carries them (``room_size``, ``obstacles``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon, Rectangle

    n = len(trajectories)
    rows = max(1, math.ceil(n / cols))
    fig, axes = plt.subplots(rows, min(cols, n), figsize=(4 * min(cols, n), 4 * rows), squeeze=False)
    for ax, traj, title in zip(axes.flat, trajectories, titles, strict=False):
        robot = np.array([s["robot"][:2] for s in traj])
        speed = np.array([math.hypot(*s["robot_vel"][:2]) for s in traj])
        members = np.array([s["members"] for s in traj])
        first, last = traj[0], traj[-1]
        sx, sy = first.get("room_size", room)
        ax.add_patch(Rectangle((-sx / 2, -sy / 2), sx, sy, fill=False, color="0.3", lw=2))
        for corners in box_corners(first.get("obstacles", np.zeros((0, 5)))):
            ax.add_patch(Polygon(corners, color="tab:brown", alpha=0.6))
        ax.add_patch(Circle(last["centre"], last["radius"], fill=False, ls="--", color="0.5"))
        for j in range(members.shape[1]):
            ax.plot(members[:, j, 0], members[:, j, 1], color="tab:blue", lw=1)
            ax.add_patch(Circle(members[-1, j], human_radius, color="tab:blue", alpha=0.8))
            ax.add_patch(Circle(members[-1, j], human_radius + personal, fill=False, color="tab:orange", lw=0.8))
            yaw = last["members_yaw"][j]
            ax.arrow(*members[-1, j], 0.4 * math.cos(yaw), 0.4 * math.sin(yaw), head_width=0.1, color="k")
        sc = ax.scatter(robot[:, 0], robot[:, 1], c=speed, cmap="viridis", s=6, vmin=0, vmax=0.4)
        ax.plot(*first["robot"][:2], "ks", ms=6)
        ax.plot(*last["slot"], "rx", ms=9, mew=2)
        (x0, x1), (y0, y1) = view_bounds(robot, members, last["slot"], last["centre"], last["radius"])
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.colorbar(sc, ax=axes, shrink=0.6, label="robot speed (m/s)")
    tmp = Path(path).with_name(f".{Path(path).name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
