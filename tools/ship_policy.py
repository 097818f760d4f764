#!/usr/bin/env python
"""Ship a trained run as one of the package's policies (ssbl_pb/policies/NAME/), with its config, its frozen
encoder (camera policies on a conv / SAEV autoencoder) and the evaluation that qualifies it (held-out seeds,
default and mixed scenarios, and mixed in random furnished rooms); `--policy NAME` then finds it in every tool.

The model is loaded before anything else. The current shipped policy is evaluated on the same seeds, and a
candidate that does worse on either scenario's success rate is refused unless --force.

    python tools/ship_policy.py runs/vector_shipped --episodes 200
    python tools/ship_policy.py runs/my_run --model final --episodes 50 --force
    python tools/ship_policy.py runs/camera_speed_saev_lstm --name camera_speed_saev --episodes 50
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, UserError, command_line, int_at_least, progress_bar, run
from ssbl_pb.files import make_stage_dir, source_commit, write_json
from ssbl_pb.policies import SHIPPED_DIR

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("default", "mixed", "mixed@furnished")  # mixed@furnished: the rooms with furniture


def pick_model(run_dir: Path, which: str) -> Path:
    """The run's best evaluated model folder or its final model, refusing a run that lacks it."""
    if not (run_dir / "config.yaml").is_file():
        raise UserError(f"{run_dir}: not a training run directory (no config.yaml)")
    if which == "best":
        if not (run_dir / "best" / "model.zip").is_file():
            raise UserError(f"{run_dir}: no best/model.zip (the run never evaluated); ship its final model with "
                            f"--model final")
        return run_dir / "best"
    if not (run_dir / "model.zip").is_file():
        raise UserError(f"{run_dir}: no final model.zip (the run did not finish); resume it, or ship --model best")
    return run_dir / "model.zip"


def evaluate(policy: str, seeds: range, label: str) -> dict[str, dict[str, float]]:
    from ssbl_pb.agents.rollout import run_episodes
    from ssbl_pb.analysis.evaluation import Setup
    from ssbl_pb.analysis.report import summarize

    results = {}
    for scenario in SCENARIOS:
        with progress_bar(len(seeds), f"{label} {scenario}") as bar:
            res = run_episodes(Setup(policy, scenario=scenario), seeds, os.cpu_count() or 1, progress=bar)
        s = summarize([r.metrics for r in res])
        results[scenario] = {k: s[k] for k in ("success_rate", "collision_rate", "violation_rate", "mean_return",
                                               "personal_zone_time_s", "mean_jerk", "arrival_speed")}
        results[scenario]["success_ci95"] = [s["metrics"]["success"]["ci_low"], s["metrics"]["success"]["ci_high"]]
    return results


def stop_workers() -> None:
    """End this process's children, the evaluation's pool workers: interrupted, a worker still loading the
    staged policy would otherwise fail on its removed files and print tracebacks after the one-line exit."""
    import multiprocessing as mp

    children = mp.active_children()
    for p in children:
        p.terminate()
    for p in children:
        p.join(5.0)


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("run", type=Path, help="training run directory")
    ap.add_argument("--episodes", type=int_at_least(1), default=200,
                    help="held-out episodes per scenario (default 200)")
    ap.add_argument("--seed", type=int_at_least(0), default=500_000, help="first held-out seed")
    ap.add_argument("--name", default="vector", help="shipped policy name (default vector)")
    ap.add_argument("--model", choices=["best", "final"], default="best",
                    help="the run's best evaluated model (best/, default) or its final one (model.zip)")
    ap.add_argument("--force", action="store_true", help="ship even if it evaluates worse than the shipped policy")
    args = ap.parse_args(argv)
    # the env, its perception and torch: after --help and argparse's errors
    from ssbl_pb.agents.trained import copy_policy, load_trained, policy_env_kwargs, resolve_model
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.training.recipe import provenance

    if not args.name.isidentifier():
        raise UserError(f"--name {args.name!r}: expected a plain name (letters, digits, _)")
    pick = pick_model(args.run, args.model)
    model, norm, config = resolve_model(str(pick))
    if norm is None:
        raise UserError(f"{model.parent}: no vecnormalize.pkl beside the model")
    # a policy on a frozen autoencoder brings its camera mode and encoder
    env = make_env(**{"obs_mode": config.get("obs_mode", "vector"), **policy_env_kwargs(str(pick))})
    load_trained(str(pick), env.observation_space)  # a corrupt or foreign model fails here, before any work
    env.close()

    dest = SHIPPED_DIR / args.name
    seeds = range(args.seed, args.seed + args.episodes)
    stage = make_stage_dir(SHIPPED_DIR, ".ship-")
    try:
        copy_policy(str(pick), stage)
        results = evaluate(str(stage), seeds, "candidate")
        current = evaluate(str(dest), seeds, "shipped") if (dest / "model.zip").is_file() else None
        worse = [sc for sc in SCENARIOS if current and results[sc]["success_rate"] < current[sc]["success_rate"]]
        if worse and not args.force:
            raise UserError(f"{args.run}: evaluates worse than the shipped '{args.name}' on the same seeds ("
                            + ", ".join(f"{sc} {results[sc]['success_rate']:.1%} vs {current[sc]['success_rate']:.1%}"
                                        for sc in worse) + "); nothing replaced (--force ships it anyway)")
        info = {"source_run": str(args.run), "source_model": str(model), "model": args.model,
                "episodes": args.episodes, "seeds": [seeds[0], seeds[-1]], "results": results,
                "replaced": current, "forced": bool(worse), "training": provenance(args.run),
                "commit": source_commit(), "command": command_line("tools/ship_policy.py", argv)}
        write_json(stage / "evaluation.json", info)
        old = SHIPPED_DIR / f".old-{args.name}"
        shutil.rmtree(old, ignore_errors=True)
        if dest.exists():
            os.replace(dest, old)
        os.replace(stage, dest)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        stop_workers()  # before their staged policy goes
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    size = sum(f.stat().st_size for f in dest.iterdir()) / 1e6
    print(json.dumps(results, indent=2))
    print(f"shipped {size:.1f} MB -> {dest}")
    return 0


if __name__ == "__main__":
    run(main)
