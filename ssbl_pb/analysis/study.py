"""Perceptual-study analysis (paper IV-B, Fig. 8): paired t-tests of Likert ratings between two conditions.

Ratings CSV, one row per rating (long format), header required:

    participant,condition,item,rating[,video]

``item`` is one of polite, sociable, rude, human_like; ``rating`` an integer 1-7 (1 "not at all", 7 "very");
``video`` (optional) names the clip when a participant rated several per condition: ratings are then averaged
per participant, condition and item before testing, as in a within-subject design.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from ..errors import UserError

ITEMS = ("polite", "sociable", "rude", "human_like")
REQUIRED = ("participant", "condition", "item", "rating")


class StudyError(UserError):
    """The ratings file is not in the documented layout; the message names the file, line and field."""


def read_ratings(path: Path) -> dict[tuple[str, str, str], list[float]]:
    """{(participant, condition, item): [ratings]} from the CSV, validated line by line."""
    path = Path(path)
    if not path.is_file():
        raise StudyError(f"{path}: file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")  # -sig: Excel's "CSV UTF-8" starts with a byte-order mark
    except UnicodeDecodeError as exc:
        raise StudyError(f"{path}: not UTF-8 text (byte {exc.start}); save it as CSV UTF-8") from None
    with io.StringIO(text, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in REQUIRED if c not in (reader.fieldnames or [])]
        if missing:
            raise StudyError(f"{path}: missing column(s) {missing}; expected a header with {list(REQUIRED)} "
                             f"(and optionally 'video')")
        out: dict[tuple[str, str, str], list[float]] = {}
        for line, row in enumerate(reader, start=2):
            item = row["item"].strip().lower().replace("-", "_")
            if item not in ITEMS:
                raise StudyError(f"{path}, line {line}: item {row['item']!r}, expected one of {list(ITEMS)}")
            try:
                rating = int(row["rating"])
            except ValueError:
                raise StudyError(f"{path}, line {line}: rating {row['rating']!r} is not an integer") from None
            if not 1 <= rating <= 7:
                raise StudyError(f"{path}, line {line}: rating {rating} outside the 1-7 Likert scale")
            out.setdefault((row["participant"].strip(), row["condition"].strip(), item), []).append(rating)
    if not out:
        raise StudyError(f"{path}: no ratings")
    return out


def paired_t(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Paired t-test of ``a - b`` with Cohen's d_z = mean(diff) / sd(diff)."""
    d = np.asarray(a, float) - np.asarray(b, float)
    res = stats.ttest_rel(a, b)
    sd = d.std(ddof=1)
    return {"t": float(res.statistic), "df": int(len(d) - 1), "p": float(res.pvalue),
            "d_z": float(d.mean() / sd) if sd > 0 else float("nan"), "mean_diff": float(d.mean())}


def analyze(path: Path, conditions: tuple[str, str] | None = None) -> dict[str, Any]:
    """Per item: each condition's mean and standard error over participants, and the paired t-test."""
    data = read_ratings(path)
    conds = sorted({c for _, c, _ in data})
    if conditions is None:
        if len(conds) != 2:
            raise StudyError(f"{path}: found conditions {conds}; name the two to compare (--conditions A B)")
        conditions = (conds[0], conds[1])
    for c in conditions:
        if c not in conds:
            raise StudyError(f"{path}: condition {c!r} not in the file (has {conds})")
    out: dict[str, Any] = {"conditions": list(conditions), "items": {}}
    for item in ITEMS:
        people = sorted({p for p, c, i in data if i == item and c in conditions})
        both = [p for p in people if all((p, c, item) in data for c in conditions)]
        if len(both) < 2:
            continue
        means = {c: np.array([np.mean(data[(p, c, item)]) for p in both]) for c in conditions}
        test = paired_t(means[conditions[0]], means[conditions[1]])
        out["items"][item] = {
            "n": len(both), "dropped": len(people) - len(both),
            **{c: {"mean": float(means[c].mean()), "se": float(means[c].std(ddof=1) / math.sqrt(len(both)))}
               for c in conditions},
            "test": test,
        }
    return out


def markdown(res: dict[str, Any]) -> str:
    a, b = res["conditions"]
    lines = [f"| item | {a} mean (SE) | {b} mean (SE) | t(df) | p | d_z |", "|---|---|---|---|---|---|"]
    for item, r in res["items"].items():
        t = r["test"]
        lines.append(f"| {item} | {r[a]['mean']:.2f} ({r[a]['se']:.2f}) | {r[b]['mean']:.2f} ({r[b]['se']:.2f}) | "
                     f"t({t['df']}) = {t['t']:.2f} | {t['p']:.3g} | {t['d_z']:.2f} |")
    return "\n".join(lines)


def plot(res: dict[str, Any], path: Path) -> None:
    """Bars with standard-error bars per item and condition, stars for p < .05 / .01 / .001 (like Fig. 8)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = res["conditions"]
    items = list(res["items"])
    x = np.arange(len(items))
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for k, (c, colour) in enumerate(((a, "tab:blue"), (b, "tab:gray"))):
        m = [res["items"][i][c]["mean"] for i in items]
        se = [res["items"][i][c]["se"] for i in items]
        ax.bar(x + (k - 0.5) * 0.38, m, 0.38, yerr=se, capsize=4, color=colour, label=c)
    for j, i in enumerate(items):
        p = res["items"][i]["test"]["p"]
        stars = "***" if p < 0.001 else "**" if p < 0.01 else "*" if p < 0.05 else "n.s."
        top = max(res["items"][i][c]["mean"] + res["items"][i][c]["se"] for c in (a, b))
        ax.text(j, top + 0.25, stars, ha="center")
    ax.set_xticks(x, [i.replace("_", "-") for i in items])
    ax.set_ylim(1, 7.8)
    ax.set_ylabel("rating (1-7)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
