#!/usr/bin/env python
"""Ship a trained run as the package's Vector policy (ssbl_pb/policies/vector/), with its config and the
evaluation that qualifies it (held-out seeds, default and mixed scenarios).

    python tools/ship_policy.py runs/vector_shipped --episodes 200
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
from pathlib import Path

from ssbl_pb.cli import fail, progress_bar, run

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="training run directory (its best/ model is shipped)")
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=500_000, help="first held-out seed")
    ap.add_argument("--name", default="vector")
    ap.add_argument("--model", choices=["best", "final"], default="best",
                    help="the run's best evaluated model (best/) or its final one (model.zip)")
    args = ap.parse_args(argv)

    from ssbl_pb.env.rollout import run_episodes
    from ssbl_pb.env.trained import ModelError, resolve_model
    from ssbl_pb.evaluation import Setup
    from ssbl_pb.policies import SHIPPED_DIR
    from ssbl_pb.report import summarize, write_json

    try:
        pick = args.run / "best" if args.model == "best" and (args.run / "best").is_dir() else args.run / "model.zip"
        model, norm, _ = resolve_model(str(pick))
    except ModelError as exc:
        return fail(exc)
    if norm is None:
        return fail(f"{model.parent}: no vecnormalize.pkl beside the model")
    dest = SHIPPED_DIR / args.name
    stage = Path(tempfile.mkdtemp(dir=SHIPPED_DIR, prefix=".ship-"))
    config = model.parent / "config.yaml" if (model.parent / "config.yaml").is_file() else args.run / "config.yaml"
    for f, name in ((model, "model.zip"), (norm, "vecnormalize.pkl"), (config, "config.yaml")):
        shutil.copy2(f, stage / name)
    results = {}
    for scenario in ("default", "mixed"):
        with progress_bar(args.episodes, scenario) as bar:
            res = run_episodes(Setup(str(stage), scenario=scenario), range(args.seed, args.seed + args.episodes),
                               os.cpu_count() or 1, progress=bar)
        s = summarize([r.metrics for r in res])
        results[scenario] = {k: s[k] for k in ("success_rate", "collision_rate", "violation_rate", "mean_return",
                                               "personal_zone_time_s", "mean_jerk", "arrival_speed")}
        results[scenario]["success_ci95"] = [s["metrics"]["success"]["ci_low"], s["metrics"]["success"]["ci_high"]]
    info = {"source_run": str(args.run), "source_model": str(model), "episodes": args.episodes,
            "seeds": [args.seed, args.seed + args.episodes - 1], "results": results,
            "command": f"python tools/ship_policy.py {args.run} --model {args.model} --episodes {args.episodes}"}
    write_json(stage / "evaluation.json", info)
    if dest.exists():
        shutil.rmtree(dest)
    os.replace(stage, dest)
    size = sum(f.stat().st_size for f in dest.iterdir()) / 1e6
    print(json.dumps(results, indent=2))
    print(f"shipped {size:.1f} MB -> {dest}")
    return 0


if __name__ == "__main__":
    run(main)
