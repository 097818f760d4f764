#!/usr/bin/env python
"""What each error of deploy's perception costs a policy: the same seeded episodes through the observation model
with one error taken away at a time, or parts of the observation from the true state (ssbl_pb/analysis/ablation.py
lists them). Writes OUT/NAME/ (evaluate.py's files per ablation), OUT/ablations.json and OUT/ablations.md (success,
shield rate and the failures by kind, docs/metrics.md).

Examples:
    python tools/ablate_perception.py --policy vector --scenario mixed --out results/ablate_mixed
    python tools/ablate_perception.py --policy runs/vector_recipe/10_vector --only model,true-members --episodes 50 \\
        --out results/ablate_run
"""

from __future__ import annotations

import os
from pathlib import Path

from ssbl_pb.analysis.ablation import ABLATIONS, pick, run_ablations
from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.files import check_output_path


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policy", default="vector", help="vector (the shipped model, default) | PATH (.zip or run dir)")
    ap.add_argument("--scenario", default="mixed", help="scenario as evaluate.py takes it (default mixed)")
    ap.add_argument("--detector", choices=["movenet", "colour"], default="movenet",
                    help="the chain whose model is ablated (default movenet, a real Pepper's)")
    ap.add_argument("--only", help="comma-separated ablations (default all): " + ", ".join(a.name for a in ABLATIONS))
    ap.add_argument("--episodes", type=int_at_least(1), default=200, help="episodes per ablation (default 200)")
    ap.add_argument("--seed", type=int_at_least(0), default=500000,
                    help="seed of the first episode (default 500000, the held-out starts); episode i uses seed+i")
    ap.add_argument("--workers", type=int_at_least(0), default=0,
                    help="processes (default 0: all cores when episodes >= 40)")
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    args = ap.parse_args(argv)
    ablations = pick(args.only)
    check_output_path(args.out)
    workers = args.workers or ((os.cpu_count() or 1) if args.episodes >= 40 else 1)
    with progress_bar(args.episodes * len(ablations), "ablate perception") as bar:
        rows = run_ablations(args.policy, args.scenario, args.detector, ablations, args.episodes, args.seed,
                             args.out, workers, bar)
    for r in rows:
        print(f"{r['name']:>22}: success {r['success_rate']:.1%}  shield {r['shield_intervention_rate']:.1%}  "
              + ", ".join(f"{k} {n}" for k, n in r["failures"].items())
              + ("" if not r["versus"] else f"  (vs {r['versus']['against']}: +{r['versus']['gained']} "
                 f"-{r['versus']['lost']}, p {r['versus']['p']:.2g})"))
    print(f"-> {args.out}/ablations.md")
    return 0


if __name__ == "__main__":
    run(main)
