"""What each error of deploy's perception costs a policy: the same seeded episodes through the observation model
(``perception.groups.observation_model``) with one of its errors taken away at a time, or parts of the observation
given from the true state (``PerceptionParams.oracle``). ``tools/ablate_perception.py`` runs them."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from ..errors import UserError
from ..files import write_json, write_text
from .compare import paired_success
from .evaluation import Setup, evaluate

NOISELESS = {"laser_std_m": 0.0, "range_std_m": 0.0, "range_std_per_m": 0.0, "bearing_std_deg": 0.0,
             "partial_std_m": 0.0, "facing_std_deg": 0.0, "facing_back_std_deg": 0.0, "facing_flip_prob": 0.0}
IN_VIEW = {"miss_prob": 0.0, "min_visible": 0.01, "hidden_fraction": 1.0}


@dataclasses.dataclass(frozen=True)
class Ablation:
    name: str
    what: str  # what it takes away, for the table
    perception: dict[str, Any]  # ``PerceptionParams`` fields changed from the chain's model


# the chain's model first (the row the others are read against), then one error at a time, then the oracles
ABLATIONS = (
    Ablation("model", "the chain's observation model as it is", {}),
    Ablation("noiseless", "no range, bearing or facing noise, no facing flips", NOISELESS),
    Ablation("no-misses", "nobody in plain sight missed", {"miss_prob": 0.0}),
    Ablation("nobody-hidden", "nobody hidden behind nearer people", {"hidden_fraction": 1.0}),
    Ablation("any-sliver", "a person found with any part of the torso in the image", {"min_visible": 0.01}),
    Ablation("every-member-in-view", "every member in the image found (the three above)", IN_VIEW),
    Ablation("true-members", "the observation's member blocks from the true state", {"oracle": ["members"]}),
    Ablation("true-place", "the observation's place from the true state", {"oracle": ["place"]}),
    Ablation("true-group", "... and its centre and o-space radius", {"oracle": ["place", "centre"]}),
    Ablation("true-all", "... and its members (the search, looks and success rule stay perception's)",
             {"oracle": ["members", "place", "centre"]}),
)
BY_NAME = {a.name: a for a in ABLATIONS}


def pick(names: str | None) -> list[Ablation]:
    """The ablations named (comma-separated; None: all), in ``ABLATIONS``' order."""
    if not names:
        return list(ABLATIONS)
    wanted = [n.strip() for n in names.split(",") if n.strip()]
    unknown = [n for n in wanted if n not in BY_NAME]
    if not wanted:
        raise UserError(f"--only {names!r}: expected some of {list(BY_NAME)}")
    if unknown:
        raise UserError(f"--only: unknown ablation(s) {unknown}; expected some of {list(BY_NAME)}")
    return [a for a in ABLATIONS if a.name in wanted]


def run_ablations(policy: str, scenario: str, detector: str, ablations: list[Ablation], episodes: int, seed: int,
                  out: Path, workers: int = 1, progress: Any = None) -> list[dict[str, Any]]:
    """Evaluate ``policy`` through each ablation of the ``detector``'s model (``out/NAME/``: evaluate's files), then
    write ``out/ablations.json`` and ``out/ablations.md``; returns the rows."""
    rows, first = [], None
    for a in ablations:
        setup = Setup(policy, scenario=scenario, env_kwargs=(("perception", {"preset": detector, **a.perception}),))
        summary, results = evaluate(setup, episodes, seed, out / a.name, workers, 0, progress)
        success = {r.seed: r.metrics["success"] for r in results}
        first = first or (a.name, success)
        rows.append({"name": a.name, "what": a.what, "success_rate": summary["success_rate"],
                     "shield_intervention_rate": summary["shield_intervention_rate"],
                     "failures": summary["failures"],
                     "versus": None if first[1] is success else paired_success(success, first[1], first[0])})
    meta = {"policy": policy, "scenario": scenario, "detector": detector, "episodes": episodes, "seed": seed}
    write_json(out / "ablations.json", {**meta, "rows": rows})
    write_text(out / "ablations.md", table(rows, meta))
    return rows


def table(rows: list[dict[str, Any]], meta: dict[str, Any]) -> str:
    """The rows as Markdown: success, shield rate, the failures by kind (``agents.metrics.failure_kind``) and each
    row against the first, seed by seed (``versus``)."""
    kinds = list(rows[0]["failures"]) if rows else []
    lines = [f"Policy `{meta['policy']}` on `{meta['scenario']}` through the `{meta['detector']}` chain's model, "
             f"{meta['episodes']} episodes from seed {meta['seed']} each.", "",
             "| ablation | what it takes away | success | shield | " + " | ".join(kinds) + " | joined / lost vs "
             f"{rows[0]['name'] if rows else '-'} (McNemar p) |",
             "|---|---|---|---|" + "---|" * len(kinds) + "---|"]
    for r in rows:
        v = r.get("versus")
        pair = "-" if not v else f"+{v['gained']} / -{v['lost']} (p {v['p']:.2g})"
        lines.append(f"| {r['name']} | {r['what']} | {100 * r['success_rate']:.1f} % | "
                     f"{100 * r['shield_intervention_rate']:.1f} % | "
                     + " | ".join(str(r["failures"][k]) for k in kinds) + f" | {pair} |")
    return "\n".join(lines) + "\n"
