"""Table I's files: ``table1.json`` (one entry per row) and ``table1.md`` (with the paper's numbers beside)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..files import write_json, write_text
from .table1 import BASELINE, RANDOM, ROWS, Budget, percent


def _stats(values: list[float]) -> tuple[float, float]:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    if not len(v):
        return float("nan"), float("nan")
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0


def aggregate(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows in the paper's order with mean and spread over seeds; percentages per seed against that seed's
    random and Vector+LSTM rows (NaN where either is missing)."""
    by = {(r["row"], r["seed"]): r for r in results}
    out = []
    for row in ROWS:
        runs = sorted((r for r in results if r["row"] == row.label), key=lambda r: r["seed"])
        if not runs:
            continue
        pcts = []
        for r in runs:
            rnd, base = by.get((RANDOM.label, r["seed"])), by.get((BASELINE.label, r["seed"]))
            ok = rnd is not None and base is not None and base["reward"] != rnd["reward"]
            pcts.append(percent(r["reward"], rnd["reward"], base["reward"]) if ok else float("nan"))
        (rew, rew_sd), (pct, pct_sd) = _stats([r["reward"] for r in runs]), _stats(pcts)
        succ, succ_sd = _stats([r["success_rate"] for r in runs])
        out.append({"row": row.label, "reward": rew, "reward_sd": rew_sd, "percent": pct, "percent_sd": pct_sd,
                    "success_rate": succ, "success_rate_sd": succ_sd, "seeds": [r["seed"] for r in runs],
                    "paper_reward": row.paper_reward, "paper_percent": row.paper_percent,
                    "steps": [r["steps"] for r in runs], "seconds": [r["seconds"] for r in runs]})
    return out


def ordering_checks(rows: list[dict[str, Any]]) -> list[tuple[str, bool | None]]:
    """The paper's ordering (issue 13's targets) as (statement, holds); None when a row is missing."""
    pct = {r["row"]: r["percent"] for r in rows if math.isfinite(r["percent"])}

    def gt(a: str, b: str) -> bool | None:
        return pct[a] > pct[b] if a in pct and b in pct else None

    def ge(a: str, b: str) -> bool | None:
        return pct[a] >= pct[b] if a in pct and b in pct else None

    only = [r.label for r in ROWS if r.obs_mode == "camera"]
    checks = [("Vector + LSTM > CameraSpeed + SAEV + LSTM", gt("Vector + LSTM", "CameraSpeed + SAEV + LSTM"))]
    for lab in only:
        checks.append((f"CameraSpeed + SAEV + LSTM > {lab}", gt("CameraSpeed + SAEV + LSTM", lab)))
        checks.append((f"{lab} > Random policy", gt(lab, "Random policy")))
    for a, b in (("CameraOnly + SAEV + FF", "CameraOnly + conv + FF"),
                 ("CameraOnly + SAEV + LSTM", "CameraOnly + conv + LSTM"),
                 ("CameraSpeed + SAEV + LSTM", "CameraSpeed + conv + LSTM")):
        checks.append((f"{a} >= {b}", ge(a, b)))
    p = pct.get("CameraSpeed + SAEV + LSTM")
    checks.append(("CameraSpeed + SAEV + LSTM >= 80 %", None if p is None else p >= 80.0))
    return checks


def _fmt(v: float | None, spread: float | None = None, digits: int = 3, unit: str = "") -> str:
    if v is None or not math.isfinite(v):
        return "-"
    s = f"{v:.{digits}f}{unit}"
    return s + (f" ± {spread:.{digits}f}" if spread is not None and math.isfinite(spread) and spread > 0 else "")


def write_table(out: Path, results: list[dict[str, Any]], budget: Budget, command: str) -> list[dict[str, Any]]:
    """Write ``out/table1.json`` and ``out/table1.md``; returns the aggregated rows."""
    rows = aggregate(results)
    write_json(out / "table1.json", rows)
    lines = [f"# Table I (budget `{budget.name}`)", "", f"Produced by `{command}`.", "",
             "Reward: the best periodic evaluation's mean return (our reward's scale, not the paper's; see "
             "ssbl_pb/analysis/table1.py for why not the smoothed training reward); percentage: 0 % = random policy, "
             f"100 % = Vector + LSTM, per seed; success: best model on {budget.test_episodes} held-out episodes "
             "(seeds from 500000). Mean ± sd over seeds.", "",
             "| row | reward | percent | success | seeds | paper reward | paper percent |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['row']} | {_fmt(r['reward'], r['reward_sd'])} | "
                     f"{_fmt(r['percent'], r['percent_sd'], 1, ' %')} | "
                     f"{_fmt(100 * r['success_rate'], 100 * r['success_rate_sd'], 0, ' %')} | {len(r['seeds'])} | "
                     f"{_fmt(r['paper_reward'])} | {_fmt(r['paper_percent'], None, 2, ' %')} |")
    lines += ["", "The paper's ordering:", ""]
    for text, ok in ordering_checks(rows):
        lines.append(f"- {text}: {'holds' if ok else 'does not hold' if ok is not None else 'row missing'}")
    lines += ["", f"Budget: {budget}", ""]
    write_text(out / "table1.md", "\n".join(lines))
    return rows
