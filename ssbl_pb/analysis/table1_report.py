"""Table I's files: ``table1.json`` (one entry per row) and ``table1.md`` (with the paper's numbers beside)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..files import write_json, write_text
from .table1 import percent
from .table1_rows import BASELINE, RANDOM, ROWS, Budget


def _stats(values: list[float]) -> tuple[float, float]:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    if not len(v):
        return float("nan"), float("nan")
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0


def _percents(runs: list[dict[str, Any]], by: dict[tuple[str, int], dict[str, Any]], key: str) -> list[float]:
    """Each run's ``key`` as a percentage against its seed's random and Vector+LSTM rows (NaN if either lacks)."""
    out = []
    for r in runs:
        rnd, base = by.get((RANDOM.label, r["seed"])), by.get((BASELINE.label, r["seed"]))
        vals = [x.get(key, float("nan")) if x else float("nan") for x in (r, rnd, base)]
        ok = all(math.isfinite(v) for v in vals) and vals[2] != vals[1]
        out.append(percent(*vals) if ok else float("nan"))
    return out


def aggregate(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows in the paper's order with mean and spread over seeds; percentages per seed against that seed's
    random and Vector+LSTM rows (NaN where either is missing). ``reward`` is the best periodic evaluation (the
    table's criterion); ``test_return`` the held-out mean return of the model it chose (``mean_return``: more
    episodes, fresh seeds, no maximum over noisy evaluations), with its own percentages beside."""
    by = {(r["row"], r["seed"]): r for r in results}
    out = []
    for row in ROWS:
        runs = sorted((r for r in results if r["row"] == row.label), key=lambda r: r["seed"])
        if not runs:
            continue
        pcts, test_pcts = _percents(runs, by, "reward"), _percents(runs, by, "mean_return")
        (rew, rew_sd), (pct, pct_sd) = _stats([r["reward"] for r in runs]), _stats(pcts)
        (ret, ret_sd), (tpct, tpct_sd) = _stats([r.get("mean_return", float("nan")) for r in runs]), _stats(test_pcts)
        succ, succ_sd = _stats([r["success_rate"] for r in runs])
        jerk, jerk_sd = _stats([r.get("jerk_cost", float("nan")) for r in runs])
        success_pcts = [100 * r["success_rate"] for r in runs]
        out.append({"row": row.label, "reward": rew, "reward_sd": rew_sd, "percent": pct, "percent_sd": pct_sd,
                    "percent_by_seed": pcts,
                    "test_return": ret, "test_return_sd": ret_sd, "test_percent": tpct,
                    "test_percent_sd": tpct_sd, "test_percent_by_seed": test_pcts,
                    "success_rate": succ, "success_rate_sd": succ_sd, "test_jerk_cost": jerk,
                    "test_jerk_cost_sd": jerk_sd, "success_percent": 100 * succ,
                    "success_percent_by_seed": success_pcts, "seeds": [r["seed"] for r in runs],
                    "paper_reward": row.paper_reward, "paper_percent": row.paper_percent,
                    "steps": [r["steps"] for r in runs], "seconds": [r["seconds"] for r in runs]})
    return out


def ordering_pairs() -> list[tuple[str, str, str]]:
    """The paper's ordering (Table I's statements) as (row a, relation, row b); relation ``>`` or ``>=``."""
    only = [r.label for r in ROWS if r.obs_mode == "camera"]
    pairs = [("Vector + LSTM", ">", "CameraSpeed + SAEV + LSTM")]
    for lab in only:
        pairs += [("CameraSpeed + SAEV + LSTM", ">", lab), (lab, ">", "Random policy")]
    pairs += [("CameraOnly + SAEV + FF", ">=", "CameraOnly + conv + FF"),
              ("CameraOnly + SAEV + LSTM", ">=", "CameraOnly + conv + LSTM"),
              ("CameraSpeed + SAEV + LSTM", ">=", "CameraSpeed + conv + LSTM")]
    return pairs


def _holds(a: float, rel: str, b: float) -> bool:
    return a > b if rel == ">" else a >= b


def ordering_checks(rows: list[dict[str, Any]], key: str = "percent") -> list[tuple[str, bool | None]]:
    """The paper's ordering on the mean percentages as (statement, holds); None when a row is missing."""
    return [(d["statement"], d["holds"]) for d in ordering_detail(rows, key)]


def ordering_detail(rows: list[dict[str, Any]], key: str = "percent") -> list[dict[str, Any]]:
    """Each ordering statement with its verdict on the means (``holds``) and, seed by seed (both rows share a
    seed's random and Vector + LSTM rows, so seeds pair): the mean difference in percentage points, the seeds
    where it holds (``seeds_holding`` of ``seeds_paired``) and a paired t-test's two-sided p (NaN under 3 seeds
    or when every difference is equal). With a handful of seeds only a large p says anything: that the
    verdict on the means may be noise. ``paper_holds``: the same statement on the paper's Table I (its
    CameraOnly + SAEV + FF, 57.06 %, is below CameraOnly + conv + FF, 61.18 %, and its best row 79.80 %).
    ``key``: ``percent`` (of the table's reward), ``test_percent`` (of the held-out return) or
    ``success_percent`` (held-out success rate in %: the task alone, without the reward's shaping and jerk cost)."""
    from scipy import stats

    by = {r["row"]: r for r in rows if math.isfinite(r.get(key, float("nan")))}
    paper = {r.label: r.paper_percent for r in ROWS if r.paper_percent is not None}
    out = []
    for a, rel, b in ordering_pairs():
        d: dict[str, Any] = {"statement": f"{a} {rel} {b}", "holds": None, "mean_diff": float("nan"),
                             "seeds_holding": 0, "seeds_paired": 0, "p_paired": float("nan"),
                             "paper_holds": _holds(paper[a], rel, paper[b]) if a in paper and b in paper else None}
        if a in by and b in by:
            d["holds"] = _holds(by[a][key], rel, by[b][key])
            pa = dict(zip(by[a]["seeds"], by[a].get(f"{key}_by_seed", []), strict=False))
            pb = dict(zip(by[b]["seeds"], by[b].get(f"{key}_by_seed", []), strict=False))
            common = [s for s in pa if s in pb and math.isfinite(pa[s]) and math.isfinite(pb[s])]
            if common:
                xa, xb = np.array([pa[s] for s in common]), np.array([pb[s] for s in common])
                diff = xa - xb
                d.update(mean_diff=float(diff.mean()), seeds_paired=len(common),
                         seeds_holding=int(sum(_holds(u, rel, v) for u, v in zip(xa, xb, strict=True))))
                if len(common) >= 3 and np.ptp(diff) > 0:
                    d["p_paired"] = float(stats.ttest_rel(xa, xb).pvalue)
        out.append(d)
    if key == "success_percent":  # the 80 % target is on the reward's percentage scale
        return out
    p = by.get("CameraSpeed + SAEV + LSTM", {}).get(key)
    out.append({"statement": "CameraSpeed + SAEV + LSTM >= 80 %", "holds": None if p is None else p >= 80.0,
                "mean_diff": float("nan"), "seeds_holding": 0, "seeds_paired": 0, "p_paired": float("nan"),
                "paper_holds": paper["CameraSpeed + SAEV + LSTM"] >= 80.0})
    return out


def _verdict(d: dict[str, Any]) -> str:
    if d["holds"] is None:
        return "row missing"
    text = "holds" if d["holds"] else "does not hold"
    if d["seeds_paired"] > 1:
        p = f", paired t p {d['p_paired']:.2g}" if math.isfinite(d["p_paired"]) else ""
        text += (f" (in {d['seeds_holding']} of {d['seeds_paired']} seeds; mean difference "
                 f"{d['mean_diff']:+.1f} points{p})")
    if d.get("paper_holds") is not None:
        text += f"; in the paper: {'holds' if d['paper_holds'] else 'does not hold'}"
    return text


def _fmt(v: float | None, spread: float | None = None, digits: int = 3, unit: str = "") -> str:
    if v is None or not math.isfinite(v):
        return "-"
    s = f"{v:.{digits}f}{unit}"
    return s + (f" ± {spread:.{digits}f}" if spread is not None and math.isfinite(spread) and spread > 0 else "")


def write_table(out: Path, results: list[dict[str, Any]], budget: Budget, command: str) -> list[dict[str, Any]]:
    """Write ``out/table1.json`` and ``out/table1.md`` from per-seed results; returns the aggregated rows."""
    rows = aggregate(results)
    write_rows(out, rows, budget, command)
    return rows


def write_rows(out: Path, rows: list[dict[str, Any]], budget: Budget, command: str) -> None:
    """Write ``out/table1.json`` and ``out/table1.md`` from aggregated rows (``aggregate``, or a table1.json read
    back: the report of a committed table is rewritten from it alone)."""
    # a table written before success_percent was kept: its mean from success_rate (no per-seed detail)
    rows = [{"success_percent": 100 * r["success_rate"], **r} for r in rows]
    write_json(out / "table1.json", rows)
    lines = [f"# Table I (budget `{budget.name}`)", "", f"Produced by `{command}`.", "",
             "Reward: the best periodic evaluation's mean return (our reward's scale, not the paper's; see "
             "ssbl_pb/analysis/table1.py for why not the smoothed training reward); percentage: 0 % = random policy, "
             f"100 % = Vector + LSTM, per seed; held-out return and success: the model that evaluation chose, on "
             f"{budget.test_episodes} held-out episodes (seeds from 500000; no maximum over noisy evaluations, so "
             "the less biased of the two); jerk cost: the part of the held-out return the smoothness term "
             "takes (our addition to the paper's reward, eq. 15; '-' where the row's trials did not record it). "
             "Mean ± sd over seeds.", "",
             "| row | reward | percent | held-out return | held-out percent | jerk cost | success | seeds "
             "| paper reward | paper percent |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    nan = float("nan")
    for r in rows:
        lines.append(f"| {r['row']} | {_fmt(r['reward'], r['reward_sd'])} | "
                     f"{_fmt(r['percent'], r['percent_sd'], 1, ' %')} | "
                     f"{_fmt(r.get('test_return', nan), r.get('test_return_sd'))} | "
                     f"{_fmt(r.get('test_percent', nan), r.get('test_percent_sd'), 1, ' %')} | "
                     f"{_fmt(r.get('test_jerk_cost', nan), r.get('test_jerk_cost_sd'), 2)} | "
                     f"{_fmt(100 * r['success_rate'], 100 * r['success_rate_sd'], 0, ' %')} | {len(r['seeds'])} | "
                     f"{_fmt(r['paper_reward'])} | {_fmt(r['paper_percent'], None, 2, ' %')} |")
    lines += ["", "The paper's ordering (on the mean percentages; per seed and a paired t-test beside: with a "
              "few seeds, a large p means the verdict may be noise; last, the same statement on the paper's own "
              "Table I):", ""]
    for d in ordering_detail(rows):
        lines.append(f"- {d['statement']}: {_verdict(d)}")
    held_out = ordering_detail(rows, "test_percent")
    if any(d["holds"] is not None for d in held_out):
        lines += ["", "The same statements on the held-out percentages:", ""]
        lines += [f"- {d['statement']}: {_verdict({**d, 'paper_holds': None})}" for d in held_out]
    lines += ["", "The same statements on the held-out success rates (the task alone: no shaping terms, no jerk "
              "cost; differences in points of success):", ""]
    lines += [f"- {d['statement']}: {_verdict({**d, 'paper_holds': None})}"
              for d in ordering_detail(rows, "success_percent")]
    lines += ["", f"Budget: {budget}", ""]
    write_text(out / "table1.md", "\n".join(lines))
