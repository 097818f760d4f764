"""A sweep's results: one row per configuration with the mean and 95 % CI over seeds of each trial metric
(``summary.csv``, ``summary.md``, ``summary.png``) and one row per trial (``trials.csv``)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..analysis.report import mean_ci, proportion_ci
from ..files import atomic_write, write_text
from .spec import SweepSpec
from .trial import METRICS, TrainEvalTrial

# columns of summary.md: (metric, heading, scale, decimals)
SHOWN = (("success_rate", "success %", 100, 1), ("mean_return", "return", 1, 2),
         ("violation_rate", "intrusion %", 100, 1), ("collision_rate", "collision %", 100, 1),
         ("personal_zone_time_s", "personal zone s", 1, 2), ("human_displacement_m", "displacement m", 1, 3),
         ("mean_jerk", "jerk m/s^3", 1, 3), ("arrival_speed", "arrival m/s", 1, 3),
         ("outside_fov_time_s", "outside view s", 1, 2))
PLOTTED = ("success_rate", "mean_return", "personal_zone_time_s", "mean_jerk")
RATES = ("success_rate", "collision_rate", "violation_rate")  # proportions of episodes: Wilson intervals
# what each metric can be: rates of episodes lie in 0-1, times, lengths and speed or jerk magnitudes are >= 0 (a t
# interval over a few seeds reaches past that; it is clipped there); the return has no bound
BOUNDS: dict[str, tuple[float, float]] = {
    **{m: (0.0, 1.0) for m in RATES},
    **{m: (0.0, math.inf) for m in ("personal_zone_time_s", "human_displacement_m", "mean_jerk", "arrival_speed",
                                    "outside_fov_time_s", "time_to_success_s", "path_length_m")}}


def rows(spec: SweepSpec, records: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One dict per configuration (grid order): its grid values, seeds finished, and per metric mean / CI."""
    return group_rows(spec.configs, spec.trials(), records)


def group_rows(groups: dict[str, dict[str, Any]], trials: Sequence[TrainEvalTrial],
               records: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One dict per group (``groups``: name -> the columns that describe it) over the finished ``trials`` of each
    (their ``group``): seeds finished and, per metric, the mean and 95 % CI over them (rates: a Wilson interval
    over the seeds' episodes, inside 0-1; ``analysis.report.proportion_ci``), each interval clipped to the
    metric's ``BOUNDS``."""
    out = []
    by_group: dict[str, list[dict[str, Any]]] = {}
    episodes: dict[str, int] = {}
    for t in trials:
        if t.name in records:
            by_group.setdefault(t.group, []).append(records[t.name]["result"])
            episodes[t.group] = t.evaluation.episodes
    for name, values in groups.items():
        results = by_group.get(name, [])
        row: dict[str, Any] = {"config": name, **values, "seeds": len(results)}
        for m in METRICS:
            seeds = [r.get(m) for r in results]
            ci = proportion_ci(seeds, episodes.get(name, 1)) if m in RATES else mean_ci(seeds)
            low, high = BOUNDS.get(m, (-math.inf, math.inf))
            row.update({f"{m}_mean": ci["mean"], f"{m}_ci_low": _clip(ci["ci_low"], low, high),
                        f"{m}_ci_high": _clip(ci["ci_high"], low, high)})
        row["_per_seed"] = results
        out.append(row)
    return out


def _clip(v: float, low: float, high: float) -> float:
    return min(max(v, low), high) if math.isfinite(v) else v


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return "" if not math.isfinite(v) else f"{v:.6g}"
    return str(v)


def _csv(table: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    fields = [k for k in table[0] if not k.startswith("_")]
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    for r in table:
        w.writerow({k: _cell(r[k]) for k in fields})
    return buf.getvalue()


def trial_rows(spec: SweepSpec, records: dict[str, dict[str, Any]], root: Path) -> list[dict[str, Any]]:
    out = []
    for t in spec.trials():
        rec = records.get(t.name)
        row: dict[str, Any] = {"trial": t.name, "config": t.group, "seed": t.config["seed"],
                               "finished": rec is not None, "node": rec.get("node", "") if rec else "",
                               "wall_s": rec.get("wall_s", "") if rec else "", "run_dir": str(root / "trials" / t.name)}
        result = rec["result"] if rec else {}
        row.update({m: result.get(m) if result.get(m) is not None else float("nan") for m in METRICS})
        out.append(row)
    return out


def _fmt(row: dict[str, Any], metric: str, scale: float, decimals: int) -> str:
    m, lo, hi = (row[f"{metric}_{k}"] for k in ("mean", "ci_low", "ci_high"))
    if not math.isfinite(m):
        return "-"
    return f"{m * scale:.{decimals}f} [{lo * scale:.{decimals}f}, {hi * scale:.{decimals}f}]"


def _pairs(d: dict[str, Any]) -> str:
    return ", ".join(f"`{k}={v}`" for k, v in d.items()) or "none"


def markdown(spec: SweepSpec, table: list[dict[str, Any]], done: int, command: str) -> str:
    ev = spec.evaluation
    total = len(spec.configs) * len(spec.seeds)
    lines = [f"# Sweep {spec.path.name}", "",
             f"`{command}`", "",
             f"- base config: `{spec.base}`; fixed overrides: {_pairs(spec.fixed)}",
             f"- grid: {_pairs(spec.grid)} ({len(spec.configs)} configurations) x seeds {list(spec.seeds)}",
             f"- trials finished: {done} of {total}" + ("" if done == total else " (run the same command to finish)"),
             f"- each trial: its {ev.model} model on {ev.episodes} held-out episodes (seeds {ev.seed}-"
             f"{ev.seed + ev.episodes - 1}, the same for every trial), scenario "
             f"{ev.scenario or 'as trained'}, default reward weights (returns comparable across configurations)",
             "- cells: mean over seeds [95 % CI: Student t over seeds; for the % of episodes a Wilson interval over "
             "the seeds' episodes, as wide as the t interval where the seeds disagree more than chance, always in "
             "0-100 %; an interval of a time, a distance, a speed or the jerk is cut at 0, as these cannot be "
             "negative]; with few seeds the CI is wide, and seed-to-seed variance is often as large as a setting's "
             "effect (docs/benchmarks.md)", "",
             "| config | seeds | " + " | ".join(h for _, h, _, _ in SHOWN) + " |",
             "|---|---|" + "---|" * len(SHOWN)]
    for r in table:
        lines.append(f"| {r['config']} | {r['seeds']} | " + " | ".join(_fmt(r, m, k, d) for m, _, k, d in SHOWN) + " |")
    lines += ["", "![per-configuration means with 95 % CIs; dots are seeds](summary.png)", "",
              "Per trial: `trials.csv` (run directories, nodes, wall time); per episode: "
              "`TRIAL/eval/episodes.csv`.", ""]
    return "\n".join(lines)


def plot(path: Path, table: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [r["config"] for r in table]
    fig, axes = plt.subplots(1, len(PLOTTED), figsize=(max(10, 1.0 * len(table) * len(PLOTTED)), 4), squeeze=False)
    for ax, metric in zip(axes.flat, PLOTTED, strict=True):
        scale = 100 if metric.endswith("_rate") else 1
        for i, r in enumerate(table):
            seeds = [v[metric] * scale for v in r["_per_seed"] if v.get(metric) is not None]
            ax.scatter([i + 0.15] * len(seeds), seeds, s=12, color="0.5", zorder=2)
            m = r[f"{metric}_mean"]
            if math.isfinite(m):
                err = [[(m - r[f"{metric}_ci_low"]) * scale], [(r[f"{metric}_ci_high"] - m) * scale]]
                ax.errorbar([i], [m * scale], yerr=err, fmt="o", color="tab:blue", capsize=4, zorder=3)
        ax.set_xticks(range(len(table)))
        ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
        ax.set_title(metric.replace("_", " ") + (" (%)" if scale == 100 else ""), fontsize=10)
        ax.set_xlim(-0.5, len(table) - 0.5)
    fig.suptitle("mean over seeds with 95 % CI (blue), one dot per seed", fontsize=10)
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=100))
    plt.close(fig)


def write_summary(out: Path, spec: SweepSpec, records: dict[str, dict[str, Any]], root: Path, command: str) -> None:
    """``summary.csv``, ``summary.md``, ``summary.png`` and ``trials.csv`` in ``out`` (each written atomically)."""
    table = rows(spec, records)
    write_text(out / "summary.csv", _csv(table))
    write_text(out / "trials.csv", _csv(trial_rows(spec, records, root)))
    write_text(out / "summary.md", markdown(spec, table, sum(r["seeds"] for r in table), command))
    plot(out / "summary.png", table)
