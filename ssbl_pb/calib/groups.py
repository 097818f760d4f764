"""F-formation statistics of real conversational groups against the simulator's groups; the groups YAML.

Per group (real or simulated), pure functions of the members' positions (m) and orientations (rad):

* member-to-centroid distance: each member's distance to the group's centroid; a group's value is their mean.
* nearest-neighbour spacing: each member's distance to its nearest fellow member.
* spacing irregularity: the coefficient of variation (std / mean) of the member-to-centroid distances (0 for a
  regular polygon and for every pair).
* orientation offset: |a member's facing - its direction to the centroid| (deg); only datasets whose
  orientations are continuous (Coffee Break's are quantised to 90 deg and are left out).

The groups YAML (``groups_yaml``) holds, per size, the quantiles of each distribution and every real layout
re-centred on its centroid; ``core.layouts.load_group_data`` reads it back.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from ..core.layouts import GroupModel
from ..params import CalibrationError, SocialParams
from .fformations import Dataset

QUANTILES = tuple(range(0, 101, 5))  # percent levels stored in the YAML
STATS = ("centroid_distance_m", "nearest_neighbour_m", "irregularity", "orientation_offset_deg")
LABELS = {"centroid_distance_m": "member-to-centroid distance (m)", "nearest_neighbour_m": "nearest neighbour (m)",
          "irregularity": "spacing irregularity (CV)", "orientation_offset_deg": "orientation offset (deg)"}
SIM_SIZES = (2, 3, 4, 5)  # the sizes the env spawns
# formations each size is spawned in by the scenarios (scenarios.BASE_SCENARIOS)
SIM_FORMATIONS = {2: ("vis_a_vis", "l_shape", "side_by_side"), 3: ("vis_a_vis", "l_shape", "side_by_side", "circular"),
                  4: ("vis_a_vis", "l_shape", "side_by_side", "circular"), 5: ("vis_a_vis", "circular")}


def group_geometry(xy: np.ndarray, yaw: np.ndarray | None = None) -> dict[str, np.ndarray | float]:
    """The four statistics of one group (``xy`` (n, 2) m, ``yaw`` (n,) rad or None); see the module docstring."""
    xy = np.asarray(xy, dtype=float)
    rel = xy - xy.mean(axis=0)
    r = np.hypot(rel[:, 0], rel[:, 1])
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    d[np.diag_indices(len(xy))] = np.inf
    out: dict[str, np.ndarray | float] = {"centroid_distance_m": float(r.mean()), "member_distance_m": r,
                                          "nearest_neighbour_m": d.min(axis=1),
                                          "irregularity": float(r.std() / r.mean()) if len(xy) > 2 else 0.0}
    if yaw is not None:
        to_c = np.arctan2(-rel[:, 1], -rel[:, 0])
        out["orientation_offset_deg"] = np.degrees(np.abs(np.remainder(np.asarray(yaw) - to_c + math.pi,
                                                                       2 * math.pi) - math.pi))
    return out


def collect(groups: Iterable[tuple[np.ndarray, np.ndarray | None]]) -> dict[int, dict[str, np.ndarray]]:
    """Per size, every value of each statistic over ``groups`` ((xy, yaw or None) pairs)."""
    acc: dict[int, dict[str, list]] = {}
    for xy, yaw in groups:
        g = group_geometry(xy, yaw)
        a = acc.setdefault(len(xy), {k: [] for k in STATS})
        for k in STATS:
            if k in g:
                a[k].append(np.atleast_1d(g[k]))
    return {n: {k: np.concatenate(v) if v else np.zeros(0) for k, v in a.items()} for n, a in sorted(acc.items())}


def real_stats(datasets: list[Dataset]) -> dict[int, dict[str, np.ndarray]]:
    """Per size, the statistics of every real group (orientations from continuous datasets only)."""
    return collect((g.xy, None if d.quantised else g.yaw) for d in datasets for g in d.groups)


def sim_stats(model: GroupModel, social: SocialParams, per_size: int = 2000, seed: int = 0,
              sizes: Iterable[int] = SIM_SIZES) -> dict[int, dict[str, np.ndarray]]:
    """The same statistics of ``per_size`` spawned groups of each of ``sizes`` (2-5), spread over the formations
    the scenarios spawn that size in (``SIM_FORMATIONS``)."""
    rng = np.random.default_rng(seed)
    layouts = []
    for n in sizes:
        forms = SIM_FORMATIONS[n]
        for k in range(per_size):
            lay = model.layout(forms[k % len(forms)], n, social, rng)
            layouts.append((lay.offsets, lay.yaw))
    return collect(layouts)


def groups_yaml(datasets: list[Dataset], min_groups: int = 1) -> dict:
    """The groups YAML's content: per size with at least ``min_groups`` groups, the quantiles of each
    statistic and every layout re-centred on its centroid (mm precision)."""
    stats = real_stats(datasets)
    if not any(n >= 2 for n in stats):
        raise CalibrationError(f"{', '.join(d.name for d in datasets)}: no complete group of 2 or more members")
    sizes: dict[int, dict] = {}
    for n, st in stats.items():
        layouts = [np.round(g.xy - g.xy.mean(axis=0), 3).ravel().tolist() for d in datasets for g in d.groups
                   if g.n == n]
        if n < 2 or len(layouts) < min_groups:
            continue
        entry: dict = {"groups": len(layouts)}
        for k in STATS:
            v = st[k]
            entry[k] = np.round(np.percentile(v, QUANTILES), 4).tolist() if len(v) else None
        entry["layouts"] = layouts
        sizes[n] = entry
    sources = [{"dataset": d.name, "groups": len(d.groups), "skipped_incomplete": len(d.skipped),
                "orientation": "quantised (not used)" if d.quantised else "continuous"} for d in datasets]
    return {"quantiles": list(QUANTILES), "sources": sources, "sizes": sizes}


def compare_table(real: dict[int, dict[str, np.ndarray]], sims: dict[str, dict[int, dict[str, np.ndarray]]]
                  ) -> list[dict]:
    """Per size 2-5: the real median of each statistic and each simulated model's, with the relative error."""
    rows = []
    for n in SIM_SIZES:
        if n not in real:
            continue
        row: dict = {"size": n, "groups": int(len(real[n]["irregularity"]))}
        for k in STATS:
            rv = real[n][k]
            row[f"real_{k}"] = float(np.median(rv)) if len(rv) else math.nan
            for name, sim in sims.items():
                sv = float(np.median(sim[n][k]))
                row[f"{name}_{k}"] = sv
                if k in ("centroid_distance_m", "nearest_neighbour_m") and len(rv):
                    row[f"{name}_{k}_error"] = sv / row[f"real_{k}"] - 1.0
        rows.append(row)
    return rows


def markdown(rows: list[dict], datasets: list[Dataset], command: str, sims: Iterable[str]) -> str:
    """The calibration report: sources, then per size the real and simulated medians (targets: member-to-
    centroid distance within 15 %, nearest neighbour within 20 %)."""
    sims = list(sims)
    lines = ["# Conversational groups: real F-formations vs the simulator", "", f"Command: `{command}`", "",
             "| dataset | complete groups | skipped (a member not located) | orientation |", "|---|---|---|---|"]
    for d in datasets:
        lines.append(f"| {d.name} | {len(d.groups)} | {len(d.skipped)} | "
                     f"{'quantised, not used' if d.quantised else 'continuous'} |")
    lines += ["", "Medians per group size (real | " + " | ".join(sims) + "); relative error of the simulated "
              "median in brackets. Targets: member-to-centroid within 15 %, nearest neighbour within 20 %.", "",
              "| size | groups | " + " | ".join(LABELS[k] for k in STATS) + " |",
              "|---|---|" + "---|" * len(STATS)]
    for r in rows:
        cells = []
        for k in STATS:
            real_v = r[f"real_{k}"]
            parts = ["-" if math.isnan(real_v) else f"{real_v:.2f}"]
            for name in sims:
                err = r.get(f"{name}_{k}_error")
                parts.append(f"{r[f'{name}_{k}']:.2f}" + (f" ({100 * err:+.0f} %)" if err is not None else ""))
            cells.append(" / ".join(parts))
        lines.append(f"| {r['size']} | {r['groups']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def figure(real: dict[int, dict[str, np.ndarray]], sims: dict[str, dict[int, dict[str, np.ndarray]]]):
    """Histograms per size (columns 2-5) and statistic (rows): real groups as bars, each model as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = [n for n in SIM_SIZES if n in real]
    fig, axes = plt.subplots(len(STATS), len(sizes), figsize=(3.2 * len(sizes), 2.4 * len(STATS)), squeeze=False)
    ranges = {"centroid_distance_m": (0, 1.6), "nearest_neighbour_m": (0, 2.2), "irregularity": (0, 0.6),
              "orientation_offset_deg": (0, 180)}
    colours = ("tab:blue", "tab:red", "tab:green")
    for row, k in enumerate(STATS):
        bins = np.linspace(*ranges[k], 25)
        for col, n in enumerate(sizes):
            ax = axes[row, col]
            rv = real[n][k]
            if len(rv):
                ax.hist(np.clip(rv, *ranges[k]), bins=bins, density=True, color="0.7", label=f"real ({len(rv)})")
            for (name, sim), c in zip(sims.items(), colours, strict=False):
                ax.hist(np.clip(sim[n][k], *ranges[k]), bins=bins, density=True, histtype="step", lw=1.5,
                        color=c, label=name)
            if row == 0:
                ax.set_title(f"groups of {n}")
            if col == 0:
                ax.set_ylabel(LABELS[k], fontsize=8)
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig

