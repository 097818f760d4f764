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

import math
import os
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "quickstart")
    ap.add_argument("--steps", type=int_at_least(2048), default=150_000,
                    help="training steps (default 150k, about 25 s)")
    ap.add_argument("--episodes", type=int_at_least(1), default=60, help="evaluation episodes per policy")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    from ssbl_pb.analysis.compare_plot import plot_summaries
    from ssbl_pb.analysis.evaluation import Setup, build_policy, evaluate
    from ssbl_pb.analysis.video import record_episode, write_mp4
    from ssbl_pb.env.approach import make_env
    from ssbl_pb.files import check_output_path, write_text
    from ssbl_pb.training.run import load_config, train

    check_output_path(args.out)
    cfg = load_config(ROOT / "configs" / "vector_ff.yaml",
                      {"total_steps": args.steps, "seed": args.seed, "name": "quickstart",
                       "eval_every": max(10_000, args.steps // 4)})
    run_dir = args.out / "run"
    steps = [("learned", str(run_dir)), ("sffm", "sffm"), ("random", "random")]
    n = len(steps) + 2
    print(f"[1/{n}] training {args.steps} steps -> {run_dir}")
    train(cfg, run_dir, overwrite=True)
    summaries = {}
    workers = os.cpu_count() or 1
    for i, (name, spec) in enumerate(steps, start=2):
        print(f"[{i}/{n}] evaluating {name} on {args.episodes} episodes")
        with progress_bar(args.episodes, name) as bar:
            summaries[name], _ = evaluate(Setup(spec), args.episodes, 1000, args.out / f"eval_{name}", workers, 6,
                                          bar)
    plot_summaries(args.out / "comparison.png", summaries,
                   title=f"default scenario, {args.episodes} episodes, 95 % CI")
    print(f"[{n}/{n}] rendering an episode of the learned policy")
    env = make_env(render_mode="rgb_array")
    top, _, _ = record_episode(env, build_policy(str(run_dir), env), 1000)
    write_mp4(args.out / "learned_episode.mp4", top)
    lines = ["# Quickstart results", "", "| policy | success | personal-zone time (s) | mean jerk | arrival speed |",
             "|---|---|---|---|---|"]
    for name, s in summaries.items():
        arrival = "-" if math.isnan(s["arrival_speed"]) else f"{s['arrival_speed']:.3f}"  # never arrived
        lines.append(f"| {name} | {s['success_rate']:.0%} | {s['personal_zone_time_s']:.2f} | {s['mean_jerk']:.3f} | "
                     f"{arrival} |")
    lines += ["", "Files: `run/learning_curve.png`, `comparison.png`, `eval_*/paths.png`, `learned_episode.mp4`."]
    write_text(args.out / "README.md", "\n".join(lines) + "\n")
    print("\n".join(lines[2:]))
    print(f"-> {args.out}/comparison.png, {args.out}/run/learning_curve.png, {args.out}/learned_episode.mp4")
    return 0


if __name__ == "__main__":
    run(main)
