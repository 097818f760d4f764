"""Learning curves like the paper's Fig. 5: smoothed episode return with the random and SFFM baselines."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..files import atomic_write


def ema(values: np.ndarray, alpha: float = 0.02) -> np.ndarray:
    """Exponentially weighted running average (the paper smooths its curves this way)."""
    out = np.empty_like(values, dtype=float)
    acc = values[0] if len(values) else 0.0
    for i, v in enumerate(values):
        acc = alpha * v + (1 - alpha) * acc
        out[i] = acc
    return out


def read_curve(path: Path) -> dict[str, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in ("step", "return", "length", "success")} if rows \
        else {k: np.zeros(0) for k in ("step", "return", "length", "success")}


def plot_learning_curve(run_dir: Path, baselines: dict[str, float]) -> Path:
    """``learning_curve.png`` from ``learning_curve.csv`` (+ ``eval.csv``); returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = run_dir / "learning_curve.csv"
    curve = read_curve(path) if path.exists() else {k: np.zeros(0) for k in ("step", "return", "success")}
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    if len(curve["step"]) == 0:
        ax.text(0.5, 0.5, "no finished training episode yet", ha="center", transform=ax.transAxes)
    ax.plot(curve["step"], curve["return"], color="0.8", lw=0.5, label="episode return")
    ax.plot(curve["step"], ema(curve["return"]), color="tab:blue", lw=2, label="smoothed (EMA)")
    styles = {"random": ("tab:red", "--"), "sffm": ("tab:green", "-.")}
    for name, value in baselines.items():
        colour, ls = styles.get(name, ("k", ":"))
        ax.axhline(value, color=colour, ls=ls, label=f"{name} baseline ({value:.2f})")
    ax.set_ylabel("episode return")
    ax.legend(fontsize=8, loc="lower right")
    ax2.plot(curve["step"], ema(curve["success"], 0.05), color="tab:blue", label="training episodes (EMA)")
    ev = run_dir / "eval.csv"
    if ev.exists():
        data = np.genfromtxt(ev, delimiter=",", names=True, ndmin=1)
        ax2.plot(data["step"], data["success_rate"], "o-", color="tab:orange", label="evaluation (fixed seeds)")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_ylabel("success rate")
    ax2.set_xlabel("environment steps")
    ax2.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    try:
        return atomic_write(run_dir / "learning_curve.png", lambda p: fig.savefig(p, dpi=110))
    finally:
        plt.close(fig)
