"""Bar charts comparing policies' summaries (means with 95 % CIs)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

DEFAULT_METRICS = (("success", "success rate"), ("personal_zone_time_s", "personal-zone time (s)"),
                   ("human_displacement_m", "members displaced (m)"), ("mean_jerk", "mean jerk (m/s³)"),
                   ("arrival_speed", "arrival speed (m/s)"), ("outside_fov_time_s", "outside members' view (s)"))


def plot_summaries(path: Path, summaries: dict[str, dict[str, Any]], metrics=DEFAULT_METRICS,
                   title: str = "") -> None:
    """One panel per metric, one bar per policy, 95 % CI error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(summaries)
    colours = ["tab:blue", "tab:green", "tab:red", "tab:purple", "tab:orange"]
    fig, axes = plt.subplots(1, len(metrics), figsize=(2.6 * len(metrics), 3.2))
    for ax, (key, label) in zip(axes, metrics, strict=True):
        for i, name in enumerate(names):
            m = summaries[name]["metrics"][key]
            lo, hi = m["mean"] - m["ci_low"], m["ci_high"] - m["mean"]
            ax.bar(i, m["mean"], yerr=[[lo], [hi]], color=colours[i % len(colours)], capsize=4)
        ax.set_xticks(range(len(names)), names, rotation=30, fontsize=8)
        ax.set_title(label, fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    tmp = Path(path).with_name(f".{Path(path).name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
