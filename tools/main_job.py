#!/usr/bin/env python
"""The main job on a small default: train a Vector policy briefly (configs/demo.yaml), evaluate it, the shipped
policy, the SFFM and random on the same starts, and write plots and a video.

Outputs (default OUT = results/quickstart): OUT/run/ (the training run: learning_curve.png, model, ...),
OUT/eval_{learned,shipped,sffm,random}/ (episodes.csv, summary.json, paths.png), OUT/comparison.png,
OUT/learned_episode.mp4 and OUT/README.md (what is where, the table with 95 % intervals).
    python tools/main_job.py                      # about 3 minutes on 2 cores
    python tools/main_job.py --steps 300000 --episodes 200
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from ssbl_pb.analysis.compare_plot import plot_summaries
from ssbl_pb.analysis.evaluation import Setup, build_policy, evaluate
from ssbl_pb.analysis.video import record_episode, write_mp4
from ssbl_pb.cli import ArgumentParser, int_at_least, int_in, progress_bar, run
from ssbl_pb.env.gymenv.approach import make_env
from ssbl_pb.files import check_output_path, write_text
from ssbl_pb.training.config import SEED_MAX, load_config

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "quickstart")
    ap.add_argument("--steps", type=int_at_least(2048), default=None,
                    help="training steps (default: configs/demo.yaml's 450k, about 1.5 min)")
    ap.add_argument("--episodes", type=int_at_least(1), default=60, help="evaluation episodes per policy")
    ap.add_argument("--seed", type=int_in(0, SEED_MAX), default=0)
    args = ap.parse_args(argv)

    from ssbl_pb.training.run import train  # lazy: torch and SB3 (~3 s), which --help does without

    check_output_path(args.out)
    over = {"seed": args.seed, "name": "quickstart"}
    if args.steps is not None:
        over |= {"total_steps": args.steps, "eval_every": max(10_000, args.steps // 9)}
    cfg = load_config(ROOT / "configs" / "demo.yaml", over)
    run_dir = args.out / "run"
    n = 6
    print(f"[1/{n}] training {cfg.total_steps} steps -> {run_dir}")
    train(cfg, run_dir, overwrite=True)
    # the final model (configs/demo.yaml says why not best/)
    steps = [("learned", str(run_dir)), ("shipped", "vector"), ("sffm", "sffm"), ("random", "random")]
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
    top, _, _ = record_episode(env, build_policy(steps[0][1], env), 1000)
    write_mp4(args.out / "learned_episode.mp4", top)
    lines = ["# Quickstart results", "",
             f"`python tools/main_job.py` ({cfg.total_steps} training steps, seed {args.seed}): {args.episodes} "
             "evaluation starts of the default scenario (seeds 1000+), the same for every policy; means with 95 % "
             "intervals (Wilson for success, Student t for the rest). learned: the model trained now; shipped: "
             "`ssbl_pb/policies/vector`.", "",
             "| policy | success | personal-zone time (s) | members displaced (m) | mean jerk (m/s^3) | "
             "arrival speed (m/s) |", "|---|---|---|---|---|---|"]

    def cell(m: dict[str, float], fmt: str) -> str:
        if not math.isfinite(m["mean"]):
            return "-"  # never arrived
        return f"{m['mean']:{fmt}} [{m['ci_low']:{fmt}}, {m['ci_high']:{fmt}}]"

    for name, s in summaries.items():
        m = s["metrics"]
        pct = {k: 100 * m["success"][k] for k in ("mean", "ci_low", "ci_high")}
        lines.append(f"| {name} | {cell(pct, '.0f')} % | {cell(m['personal_zone_time_s'], '.2f')} | "
                     f"{cell(m['human_displacement_m'], '.3f')} | {cell(m['mean_jerk'], '.3f')} | "
                     f"{cell(m['arrival_speed'], '.3f')} |")
    lines += ["", "Files: `run/learning_curve.png`, `comparison.png`, `eval_*/paths.png`, `learned_episode.mp4`."]
    write_text(args.out / "README.md", "\n".join(lines) + "\n")
    print("\n".join(lines[4:]))
    print(f"-> {args.out}/comparison.png, {args.out}/run/learning_curve.png, {args.out}/learned_episode.mp4")
    return 0


if __name__ == "__main__":
    run(main)
