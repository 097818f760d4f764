"""Learned policy vs SFFM from the same start states: paired tests, side-by-side paths, speed profiles."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from ..agents import metrics
from ..errors import UserError
from .report import mean_ci

# the five social measures of the targets: lower is better for each
SOCIAL = ("personal_zone_time_s", "human_displacement_m", "mean_jerk", "arrival_speed", "outside_fov_time_s")
BINARY = tuple(k for k, (unit, *_rest) in metrics.METRICS.items() if unit == "0/1")  # McNemar's test
# each metric's direction is in agents.metrics.METRICS; the rest is descriptive
LOWER_IS_BETTER = metrics.LOWER_IS_BETTER
HIGHER_IS_BETTER = {*metrics.HIGHER_IS_BETTER, "return"}


def paired_test(a: list[float], b: list[float], binary: bool) -> dict[str, float]:
    """Paired comparison of ``a`` (learned) and ``b`` (baseline) over the same seeds.

    Binary metrics: exact McNemar test on the discordant pairs. Others: Wilcoxon signed-rank test on the
    pairs where both are finite (distributions such as jerk are far from normal); the effect size is the
    matched-pairs rank-biserial correlation.
    """
    x, y = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if binary:
        n10, n01 = int(np.sum((x == 1) & (y == 0))), int(np.sum((x == 0) & (y == 1)))
        p = 1.0 if n10 + n01 == 0 else float(stats.binomtest(n10, n10 + n01, 0.5).pvalue)
        return {"test": "mcnemar", "n": int(len(x)), "a_only": n10, "b_only": n01, "p": p}
    d = x - y
    if len(d) == 0 or np.all(d == 0):
        return {"test": "wilcoxon", "n": int(len(d)), "p": 1.0, "effect": 0.0, "median_diff": 0.0}
    res = stats.wilcoxon(x, y, zero_method="wilcox")
    nz = d[d != 0]
    ranks = stats.rankdata(np.abs(nz))
    effect = float((ranks[nz > 0].sum() - ranks[nz < 0].sum()) / ranks.sum())
    return {"test": "wilcoxon", "n": int(len(d)), "p": float(res.pvalue), "effect": effect,
            "median_diff": float(np.median(d))}


def paired_success(success: dict[int, float], other: dict[int, float], name: str) -> dict[str, Any]:
    """One evaluation's episodes against another's (``name``), seed by seed (the same starts): how many it joined
    that the other did not (``gained``), the reverse (``lost``), and McNemar's exact p on those discordant pairs
    (``paired_test``). Two evaluations of 200 starts differ by +-2.5 points by chance alone; the pairs tell whether
    a difference is more than that."""
    seeds = sorted(success)
    t = paired_test([success[s] for s in seeds], [other[s] for s in seeds], binary=True)
    return {"against": name, "gained": t["a_only"], "lost": t["b_only"], "p": t["p"]}


def read_success(folder: Path, seeds: list[int]) -> dict[int, float]:
    """Success by seed from an evaluation's ``folder/episodes.csv`` (``tools/evaluate.py``), for every one of
    ``seeds``; a missing file, column or seed is refused by name."""
    path = Path(folder) / "episodes.csv"
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise UserError(f"{path}: cannot read an evaluation's episodes ({e.strerror or e})") from None
    if not rows or not {"seed", "success"} <= set(rows[0]):
        raise UserError(f"{path}: expected the columns 'seed' and 'success' (tools/evaluate.py's episodes.csv)")
    have = {int(float(r["seed"])): float(r["success"]) for r in rows}
    missing = [s for s in seeds if s not in have]
    if missing:
        raise UserError(f"{path}: no episodes with seeds {missing[:3]}{' ...' if len(missing) > 3 else ''} "
                        f"({len(missing)} of {len(seeds)}); it holds seeds {min(have)}-{max(have)}: evaluate the "
                        "same --seed and --episodes")
    return {s: have[s] for s in seeds}


def compare_rows(learned: list[dict[str, float]], baseline: list[dict[str, float]], alpha: float = 0.05
                 ) -> dict[str, Any]:
    """Per metric: means with 95 % CIs for both, the paired test, and which side is better.

    A side is better when the test finds it lower (or higher, by the metric's direction) at ``alpha`` and its
    mean says the same: for McNemar's, the rarer of the discordant pairs (the means agree); for Wilcoxon's
    signed-rank test, the sign of its rank-biserial effect, which can disagree with the means when a few pairs
    differ by much (members displaced: the learned robot displaced members less in most pairs, more in
    a tail of starts beside a member, and its mean was the higher one). Then neither is ("by the mean
    and a paired test"); ``mean_diff`` keeps the means' side in view."""
    out: dict[str, Any] = {}
    for key in learned[0]:
        if key == "seed":
            continue
        a, b = [r[key] for r in learned], [r[key] for r in baseline]
        test = paired_test(a, b, key in BINARY)
        ma, mb = mean_ci(a), mean_ci(b)
        test["mean_diff"] = ma["mean"] - mb["mean"] if math.isfinite(ma["mean"]) and math.isfinite(mb["mean"]) \
            else math.nan
        shift = test["mean_diff"] if test["test"] == "mcnemar" else test["effect"]
        better = None
        directed = key in LOWER_IS_BETTER or key in HIGHER_IS_BETTER
        md = test["mean_diff"]
        agree = math.isfinite(shift) and math.isfinite(md) and shift * md > 0  # the test's side and the means' side
        if directed and test["p"] < alpha and agree:
            better = "learned" if (shift < 0) == (key in LOWER_IS_BETTER) else "baseline"
        out[key] = {"learned": ma, "baseline": mb, "test": test, "better": better}
    return out


def markdown_table(cmp: dict[str, Any], names: tuple[str, str] = ("learned", "SFFM")) -> str:
    lines = [f"| metric | {names[0]} (95 % CI) | {names[1]} (95 % CI) | test | p | effect | better |",
             "|---|---|---|---|---|---|---|"]

    def fmt(m: dict[str, float]) -> str:
        if not math.isfinite(m["mean"]):
            return "n/a"
        return f"{m['mean']:.3g} [{m['ci_low']:.3g}, {m['ci_high']:.3g}]"

    for key, c in cmp.items():
        t = c["test"]
        mark = {"learned": names[0], "baseline": names[1], None: ""}[c["better"]]
        lines.append(f"| {key}{' **' if key in SOCIAL else ''} | {fmt(c['learned'])} | {fmt(c['baseline'])} | "
                     f"{t['test']} (n={t['n']}) | {t['p']:.2g} | {_effect(t)} | {mark} |")
    return "\n".join(lines)


def _effect(test: dict[str, Any]) -> str:
    """The table's effect column: Wilcoxon's rank-biserial r (+: learned higher in more pairs, weighted by rank)
    with the median pair difference; McNemar's discordant pairs (learned only / baseline only)."""
    if test["test"] == "mcnemar":
        return f"{test['a_only']} / {test['b_only']}"
    return f"r {test['effect']:+.2f}, median {test['median_diff']:+.3g}"


def speed_profile(trajectories: list[list[dict[str, Any]]], bins: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean robot speed and its 95 % CI half-width per bin of distance to the group centre."""
    dist, speed = [], []
    for traj in trajectories:
        for s in traj:
            dist.append(math.hypot(*(s["robot"][:2] - s["centre"])))
            speed.append(math.hypot(*s["robot_vel"][:2]))
    dist, speed = np.asarray(dist), np.asarray(speed)
    idx = np.digitize(dist, bins) - 1
    mean = np.full(len(bins) - 1, np.nan)
    half = np.full(len(bins) - 1, np.nan)
    for i in range(len(bins) - 1):
        v = speed[idx == i]
        if len(v) >= 3:
            mean[i] = v.mean()
            half[i] = 1.96 * v.std(ddof=1) / math.sqrt(len(v))
    return mean, half


def plot_speed_vs_distance(path: Path, groups: dict[str, list[list[dict[str, Any]]]], max_dist: float = 6.0) -> None:
    """The paper's hypothesis, made visible: speed as a function of the distance to the group."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bins = np.arange(0.5, max_dist + 0.25, 0.25)
    mid = 0.5 * (bins[1:] + bins[:-1])
    fig, ax = plt.subplots(figsize=(6, 4))
    for (name, trajs), colour in zip(groups.items(), ("tab:blue", "tab:green", "tab:red"), strict=False):
        mean, half = speed_profile(trajs, bins)
        ax.plot(mid, mean, color=colour, label=name)
        ax.fill_between(mid, mean - half, mean + half, color=colour, alpha=0.2)
    ax.set_xlabel("distance to the group centre (m)")
    ax.set_ylabel("robot speed (m/s)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    tmp = Path(path).with_name(f".{Path(path).name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
