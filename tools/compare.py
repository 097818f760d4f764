#!/usr/bin/env python
"""Learned policy vs the SFFM baseline from the same start states.

Writes into OUT: report.md (every metric with 95 % CIs and a paired test), comparison.json, paths.png (paths
side by side for a few starts, like the paper's Fig. 6), speed_vs_distance.png (the paper's hypothesis:
accelerating and decelerating with the social feedback), and videos/SEED_{learned,sffm}.mp4 pairs from the same
starts for a perceptual study.
    python tools/compare.py --episodes 200 --out results/compare
    python tools/compare.py --policy runs/my_run --scenario mixed --episodes 100 --out results/compare_mixed
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ssbl_pb.agents.rollout import run_episodes
from ssbl_pb.analysis.compare import SOCIAL, compare_rows, markdown_table, plot_speed_vs_distance
from ssbl_pb.analysis.evaluation import Setup, build_policy, check_policy_spec, outcome
from ssbl_pb.analysis.report import plot_paths, write_json
from ssbl_pb.analysis.video import record_episode, write_mp4
from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.env.gymenv.approach import make_env
from ssbl_pb.files import check_output_path, output_dir, write_text

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policy", default="vector", help="the learned policy: vector (shipped) or a run dir / .zip")
    ap.add_argument("--baseline", default="sffm", help="sffm | straight | random | another model")
    ap.add_argument("--episodes", type=int_at_least(2), default=200, help="paired episodes (default 200)")
    ap.add_argument("--seed", type=int_at_least(0), default=500_000, help="first held-out seed (default 500000)")
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--pairs", type=int_at_least(0), default=3,
                    help="starts drawn side by side and rendered as mp4 pairs (default 3)")
    ap.add_argument("--workers", type=int_at_least(0), default=0, help="processes (default 0: all cores)")
    args = ap.parse_args(argv)

    workers = args.workers or os.cpu_count() or 1
    check_policy_spec(args.policy)
    check_policy_spec(args.baseline, "--baseline")
    check_output_path(args.out)
    seeds = range(args.seed, args.seed + args.episodes)
    setups = {"learned": Setup(args.policy, scenario=args.scenario),
              "sffm": Setup(args.baseline, scenario=args.scenario)}
    for setup in setups.values():
        setup()[0].close()  # a bad model, obs mode or scenario fails here, before any episode
    results = {}
    for name, setup in setups.items():
        with progress_bar(args.episodes, name) as bar:
            results[name] = run_episodes(setup, seeds, workers, keep_trajectories=args.episodes, progress=bar)
    with output_dir(args.out):
        report(args, results, seeds)
    return 0


def report(args: Any, results: dict[str, list[Any]], seeds: range) -> None:
    """comparison.json, paths.png, speed_vs_distance.png, videos/ and report.md in ``args.out``."""
    rows = {k: [r.metrics for r in v] for k, v in results.items()}
    cmp = compare_rows(rows["learned"], rows["sffm"])
    better = [k for k in SOCIAL if cmp[k]["better"] == "learned"]
    worse = [k for k in SOCIAL if cmp[k]["better"] == "baseline"]
    verdict = {"learned_better_on": better, "learned_worse_on": worse,
               "target_met": len(better) >= 3 and not worse}
    write_json(args.out / "comparison.json", {"policy": args.policy, "baseline": args.baseline,
                                              "scenario": args.scenario, "seeds": [seeds.start, seeds.stop - 1],
                                              "verdict": verdict, "metrics": cmp})
    room = make_env().unwrapped.world_params.room_size
    trajs, titles = [], []
    for i in range(min(args.pairs, args.episodes)):
        for name in ("learned", "sffm"):
            r = results[name][i]
            trajs.append(r.trajectory)
            titles.append(f"{name}, seed {r.seed}: {outcome(r.metrics)}")
    if trajs:
        plot_paths(args.out / "paths.png", trajs, titles, room, cols=2)
    plot_speed_vs_distance(args.out / "speed_vs_distance.png",
                           {"learned": [r.trajectory for r in results["learned"]],
                            "SFFM": [r.trajectory for r in results["sffm"]]})
    (args.out / "videos").mkdir(exist_ok=True)
    for i in range(min(args.pairs, args.episodes)):
        seed = seeds.start + i
        for name, spec in (("learned", args.policy), ("sffm", args.baseline)):
            env = make_env(scenario=args.scenario, render_mode="rgb_array")
            top, _, _ = record_episode(env, build_policy(spec, env), seed)
            write_mp4(args.out / "videos" / f"{seed}_{name}.mp4", top)
            env.close()
    text = [f"# {args.policy} vs {args.baseline}", "",
            f"Scenario `{args.scenario}`, {args.episodes} paired episodes (seeds {seeds.start}-{seeds.stop - 1}). "
            f"Metrics marked ** are the five social measures of the target; lower is better for each. `better` is the "
            f"side the paired test finds lower or higher at p < 0.05 (Wilcoxon: the sign of its rank-biserial "
            f"effect r, which counts pairs, not metres; McNemar: the discordant pairs, learned only / SFFM only) when "
            f"its mean says the same; where r and the means disagree (a few pairs differ by much), neither is.", "",
            markdown_table(cmp, ("learned", args.baseline)), "",
            f"Learned better (by the mean and p < 0.05) on: {', '.join(better) or 'none'}; "
            f"worse on: {', '.join(worse) or 'none'}.",
            f"Target (better on >= 3, worse on none): {'met' if verdict['target_met'] else 'NOT met'}.", "",
            "Files: `paths.png`, `speed_vs_distance.png`, `videos/`."]
    write_text(args.out / "report.md", "\n".join(text) + "\n")
    print("\n".join(text[4:-1]))


if __name__ == "__main__":
    run(main)
