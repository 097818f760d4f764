"""Policies evaluated per scenario and observation model on held-out seeded episodes (``tools/bench_policies.py``),
and seeds of one recipe summarised as mean and spread (``tools/bench_seeds.py``)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..agents.rollout import run_episodes
from ..analysis.evaluation import Setup, check_policy_spec
from ..analysis.report import summarize
from ..cli import int_at_least, progress_bar
from ..errors import UserError

PERCEPTIONS = ("off", "on", "movenet", "colour")
# the paper's social measures the comparison with the SFFM judges (``analysis.compare``), and success
MEASURES = ("success_rate", "personal_zone_time_s", "human_displacement_m", "arrival_speed", "mean_jerk")


def add_bench_args(ap: Any, scenarios: str, perception: str) -> None:
    """The evaluation's flags both bench tools take: ``--scenarios``, ``--perception``, ``--episodes``, ``--seed``
    (with these defaults)."""
    ap.add_argument("--scenarios", default=scenarios, help="comma list of scenarios; SCENARIO:ROOM_YAML plays it "
                    f"with that room YAML (e.g. default@map:results/rooms/lab.yaml); default {scenarios}")
    ap.add_argument("--perception", default=perception, help="comma list of off (the true state), on or movenet "
                    "(the group as deploy's perception sees it: the observation model of a real Pepper's MoveNet "
                    f"chain) and colour (the model of the colour detector on box proxies); default {perception}")
    ap.add_argument("--episodes", type=int_at_least(1), default=200, help="episodes per scenario (default 200)")
    ap.add_argument("--seed", type=int_at_least(0), default=500_000, help="first held-out seed")


def check_perceptions(percs: list[str]) -> None:
    bad = sorted(set(percs) - set(PERCEPTIONS))
    if bad:
        raise UserError(f"--perception {','.join(bad)}: expected a comma list of {', '.join(PERCEPTIONS)}")


def setup(pol: str, sc: str, perc: str) -> Setup:
    """A policy's evaluation on ``sc`` (SCENARIO or SCENARIO:ROOM_YAML) with the observation model ``perc``."""
    name, _, room = sc.partition(":")
    kwargs: tuple = (("room_yaml", room),) if room else ()
    model = True if perc == "on" else perc
    return Setup(pol, scenario=name, env_kwargs=kwargs + ((("perception", model),) if perc != "off" else ()))


def bench_table(pols: list[str], scs: list[str], percs: list[str], episodes: int, seed: int,
                row_name: Any = None) -> dict[str, dict[str, dict]]:
    """{row: {scenario: summary}} for every policy and model (``row_name(pol, perc)`` names the rows; default the
    policy, with the model where more than off is asked), each over ``episodes`` seeds from ``seed``. Every
    policy and scenario is checked before the first episode."""
    check_perceptions(percs)
    for pol in pols:
        check_policy_spec(pol, "--policies")
        for sc in scs:
            setup(pol, sc, percs[-1])()[0].close()
    if row_name is None:
        def row_name(pol: str, perc: str) -> str:
            return pol if percs == ["off"] else f"{pol} (perception {perc})"
    table: dict[str, dict[str, dict]] = {}
    for pol in pols:
        for perc in percs:
            row = row_name(pol, perc)
            for sc in scs:
                with progress_bar(episodes, f"{row} {sc}") as bar:
                    res = run_episodes(setup(pol, sc, perc), range(seed, seed + episodes), os.cpu_count() or 1,
                                       progress=bar)
                s = summarize([r.metrics for r in res])
                table.setdefault(row, {})[sc] = {k: s[k] for k in (
                    "success_rate", "collision_rate", "violation_rate", "personal_zone_time_s", "mean_jerk",
                    "arrival_speed", "human_displacement_m")}
                table[row][sc]["obstacle_collision_rate"] = s["metrics"]["obstacle_collision"]["mean"]
                table[row][sc]["success_ci"] = [s["metrics"]["success"]["ci_low"], s["metrics"]["success"]["ci_high"]]
    return table


def seed_spread(table: dict[str, dict[str, dict]], seeds: list[str], percs: list[str], scs: list[str]
                ) -> dict[str, dict[str, dict[str, dict[str, Any]]]]:
    """{perception: {scenario: {measure: {mean, std, values}}}} over the seeds' rows ``table[(seed, perc)]``
    (``bench_table`` with ``row_name`` giving ``f"{seed} ({perc})"``); std is the sample's (ddof 1; 0 for one)."""
    out: dict[str, dict[str, dict[str, dict[str, Any]]]] = {}
    for perc in percs:
        for sc in scs:
            for m in (*MEASURES, "violation_rate"):
                vals = np.array([table[f"{s} ({perc})"][sc][m] for s in seeds], dtype=float)
                out.setdefault(perc, {}).setdefault(sc, {})[m] = {
                    "mean": float(np.nanmean(vals)), "std": float(np.nanstd(vals, ddof=1)) if len(vals) > 1 else 0.0,
                    "values": vals.tolist()}
    return out


def spread_markdown(spread: dict, scs: list[str]) -> str:
    """One table per observation model: a row per measure, a column per scenario, mean +- std over the seeds."""
    fmt = {"success_rate": lambda v: f"{100 * v:.1f} %", "violation_rate": lambda v: f"{100 * v:.1f} %",
           "personal_zone_time_s": lambda v: f"{v:.2f} s", "human_displacement_m": lambda v: f"{v:.3f} m",
           "arrival_speed": lambda v: f"{v:.3f} m/s", "mean_jerk": lambda v: f"{v:.3f}"}
    text = []
    for perc, rows in spread.items():
        text += [f"Observation model {perc}:", "", "| measure | " + " | ".join(scs) + " |", "|---|" + "---|" * len(scs)]
        for m in (*MEASURES, "violation_rate"):
            f = fmt[m]
            cells = [f"{f(rows[sc][m]['mean'])} ± {f(rows[sc][m]['std']).split()[0]}" for sc in scs]
            text.append(f"| {m} | " + " | ".join(cells) + " |")
        text.append("")
    return "\n".join(text)


def plot_spread(spread: dict, scs: list[str], seeds: list[str], path: Any) -> None:
    """Success per scenario (a bar per observation model at the seeds' mean, a dot per seed) and the four social
    measures (per seed, the model off or the first one asked), written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 5, figsize=(20, 4), gridspec_kw={"width_ratios": [3, 1, 1, 1, 1]})
    percs, width = list(spread), 0.8 / max(len(spread), 1)
    x = np.arange(len(scs))
    for k, perc in enumerate(percs):
        means = [spread[perc][sc]["success_rate"]["mean"] * 100 for sc in scs]
        axes[0].bar(x + k * width, means, width, label=f"model {perc}", alpha=0.6)
        for j, sc in enumerate(scs):
            vals = np.array(spread[perc][sc]["success_rate"]["values"]) * 100
            axes[0].plot(np.full(len(vals), x[j] + k * width), vals, "k.", ms=6)
    axes[0].set_xticks(x + width * (len(percs) - 1) / 2, scs, rotation=20, fontsize=8)
    axes[0].set_ylabel("success (%)")
    axes[0].set_ylim(0, 105)
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"{len(seeds)} seeds: bar = mean, dot = a seed")
    first = percs[0]
    for ax, m in zip(axes[1:], MEASURES[1:], strict=True):
        for j, sc in enumerate(scs):
            vals = spread[first][sc][m]["values"]
            ax.plot(np.full(len(vals), j), vals, "o", ms=5)
        ax.set_xticks(range(len(scs)), scs, rotation=40, fontsize=7)
        ax.set_title(f"{m} (model {first})", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
