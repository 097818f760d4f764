#!/usr/bin/env python
"""Evaluate a policy over seeded episodes: DIR/episodes.csv, DIR/summary.json, DIR/paths.png.

Examples:
    python tools/evaluate.py --policy sffm --episodes 200 --out results/eval_sffm
    python tools/evaluate.py --policy vector --scenario mixed --episodes 200 --out results/eval_vector_mixed
    python tools/evaluate.py --policy runs/ppo_vector --episodes 50 --out results/eval_run
    python tools/evaluate.py --policy sffm --groups paper --episodes 200 --out results/eval_sffm_paper
    python tools/evaluate.py --policy vector --scenario mixed --perception movenet --episodes 200 --seed 500000 \
        --out results/eval_b --against results/eval_a    # seed by seed: joined / lost, McNemar's p
"""

from __future__ import annotations

import os
from pathlib import Path

from ssbl_pb.analysis.evaluation import Setup, evaluate
from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.files import write_json


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policy", required=True,
                    help="sffm | random | straight | vector (the shipped model) | PATH (.zip or run directory)")
    ap.add_argument("--episodes", type=int_at_least(1), default=100, help="number of episodes (default 100)")
    ap.add_argument("--seed", type=int_at_least(0), default=1000,
                    help="seed of the first episode; episode i uses seed+i")
    ap.add_argument("--obs-mode", default="vector", choices=["vector", "camera", "camera_speed"])
    ap.add_argument("--scenario", default="default",
                    help="default | mixed | behind | FORMATION[-N] | a,b,...; each may end in "
                         "@empty, @furnished or @map (the --room-yaml room)")
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    ap.add_argument("--workers", type=int_at_least(0), default=0,
                    help="processes (default 0: all cores when episodes >= 40)")
    ap.add_argument("--paths", type=int_at_least(0), default=6,
                    help="episodes drawn in paths.png (default 6; 0: no plot)")
    ap.add_argument("--groups", choices=["calibrated", "paper"],
                    help="where members stand: as real groups do (calibrated, the default) or on the paper's 1.0 m "
                         "o-space circle (paper)")
    ap.add_argument("--perception", choices=["off", "on", "movenet", "colour"], default="off",
                    help="the policy sees the true state (off, default) or the group as deploy's perception would "
                         "see it through Pepper's camera (the observation model, "
                         "ssbl_pb/perception/groups/observation_model.py): on = movenet, a real Pepper's chain; "
                         "colour, the virtual Pepper's colour detector on box proxies")
    ap.add_argument("--shield", choices=["auto", "on", "off"], default="auto",
                    help="a trained policy's safety shield: as trained (auto, default), or forced on/off")
    ap.add_argument("--against", type=Path,
                    help="another evaluation's folder of the same --seed and --episodes: pair this one's episodes "
                         "with its, seed by seed (joined / lost and McNemar's p, in summary.json's 'against')")
    for name, what in (("camera", "tools/calibrate_camera.py"), ("robot", "tools/identify_dynamics.py"),
                       ("social", "tools/calibrate_humans.py"), ("room", "tools/import_map.py"),
                       ("groups", "tools/calibrate_groups.py")):
        ap.add_argument(f"--{name}-yaml", help=f"calibrated {name} parameters ({what}'s output)")
    args = ap.parse_args(argv)

    workers = args.workers or ((os.cpu_count() or 1) if args.episodes >= 40 else 1)
    calib = tuple((f"{k}_yaml", v) for k in ("camera", "robot", "social", "room", "groups")
                  if (v := getattr(args, f"{k}_yaml")) is not None)
    if args.groups is not None:
        calib += (("groups", args.groups),)
    if args.perception != "off":
        calib += (("perception", True if args.perception == "on" else args.perception),)
    shield = {"auto": None, "on": True, "off": False}[args.shield]
    setup = Setup(args.policy, args.obs_mode, args.scenario, calib, shield)
    other = None
    if args.against is not None:  # read before any episode runs (scipy's tests load only when asked for)
        from ssbl_pb.analysis.compare import paired_success, read_success

        other = read_success(args.against, list(range(args.seed, args.seed + args.episodes)))
    with progress_bar(args.episodes, f"evaluate {args.policy}") as bar:
        summary, results = evaluate(setup, args.episodes, args.seed, args.out, workers, args.paths, bar)
    if other is not None:
        summary["against"] = paired_success({r.seed: r.metrics["success"] for r in results}, other, str(args.against))
        write_json(args.out / "summary.json", summary)
    print(f"perception {summary['perception']}  success {summary['success_rate']:.1%}  "
          f"collision {summary['collision_rate']:.1%}  "
          f"shield {summary['shield_intervention_rate']:.1%} of steps  "
          f"return {summary['mean_return']:.3f}  personal-zone {summary['personal_zone_time_s']:.2f}s  "
          f"-> {args.out}/summary.json")
    if summary.get("shield_rules"):  # which of the shield's rules changed the steps (core.shield.RULES)
        print("shield by rule: " + ", ".join(f"{k} {v:.1%}" for k, v in summary["shield_rules"].items()))
    if "failures" in summary:  # through the observation model: why the others failed (metrics.failure_kind)
        print("failures: " + ", ".join(f"{k} {n}" for k, n in summary["failures"].items()))
    if "against" in summary:
        v = summary["against"]
        print(f"against {v['against']}: joined {v['gained']} it did not, lost {v['lost']} it joined "
              f"(McNemar p {v['p']:.2g})")
    return 0


if __name__ == "__main__":
    run(main)
