#!/usr/bin/env python
"""The main job on a small default: train a Vector policy briefly, evaluate it against the SFFM and random
baselines, and write plots and a video.

Outputs (default OUT = results/quickstart): OUT/run/ (the training run: learning_curve.png, model, ...),
OUT/eval_{learned,sffm,random}/ (episodes.csv, summary.json, paths.png), OUT/comparison.png,
OUT/learned_episode.mp4 and OUT/README.md (what is where, with the headline numbers).
    python tools/main_job.py                      # about 3 minutes on 2 cores
    python tools/main_job.py --steps 300000 --episodes 200
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ssbl_pb.cli import fail, progress_bar, run

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "quickstart")
    ap.add_argument("--steps", type=int, default=150_000, help="training steps (default 150k, about 25 s)")
    ap.add_argument("--episodes", type=int, default=60, help="evaluation episodes per policy")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    from ssbl_pb.compare_plot import plot_summaries
    from ssbl_pb.evaluation import Setup, UsageError, evaluate
    from ssbl_pb.training.run import ConfigError, RunError, load_config, train

    try:
        cfg = load_config(ROOT / "configs" / "vector_ff.yaml",
                          {"total_steps": args.steps, "seed": args.seed, "name": "quickstart",
                           "eval_every": max(10_000, args.steps // 4)})
        run_dir = args.out / "run"
        print(f"[1/3] training {args.steps} steps -> {run_dir}")
        train(cfg, run_dir, overwrite=True)
        summaries = {}
        workers = os.cpu_count() or 1
        for name, spec in (("learned", str(run_dir)), ("sffm", "sffm"), ("random", "random")):
            print(f"[2/3] evaluating {name} on {args.episodes} episodes")
            with progress_bar(args.episodes, name) as bar:
                summaries[name], _ = evaluate(Setup(spec), args.episodes, 1000, args.out / f"eval_{name}", workers,
                                              6, bar)
        plot_summaries(args.out / "comparison.png", summaries,
                       title=f"default scenario, {args.episodes} episodes, 95 % CI")
        print("[3/3] rendering an episode of the learned policy")
        from ssbl_pb.env.approach import make_env
        from ssbl_pb.evaluation import build_policy
        from ssbl_pb.video import record_episode, write_mp4

        env = make_env(render_mode="rgb_array")
        top, _, _ = record_episode(env, build_policy(str(run_dir), env), 1000)
        write_mp4(args.out / "learned_episode.mp4", top)
    except (ConfigError, RunError, UsageError, ValueError, OSError) as exc:
        return fail(exc)
    lines = ["# Quickstart results", "", "| policy | success | personal-zone time (s) | mean jerk | arrival speed |",
             "|---|---|---|---|---|"]
    for name, s in summaries.items():
        lines.append(f"| {name} | {s['success_rate']:.0%} | {s['personal_zone_time_s']:.2f} | {s['mean_jerk']:.3f} | "
                     f"{s['arrival_speed']:.3f} |")
    lines += ["", "Files: `run/learning_curve.png`, `comparison.png`, `eval_*/paths.png`, `learned_episode.mp4`."]
    (args.out / "README.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines[2:]))
    print(f"-> {args.out}/comparison.png, {args.out}/run/learning_curve.png, {args.out}/learned_episode.mp4")
    return 0


if __name__ == "__main__":
    run(main)
