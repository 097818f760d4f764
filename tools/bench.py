#!/usr/bin/env python
"""Simulator speed on one core: raw PyBullet stepping and TinyRenderer (the limits), the world with humans
moving by social forces, first-person frames at 84x84 and 128x128, frames with five people in view drawn as box
proxies and as bodies (``humans.appearance``) at 320x240 and 640x480, and the Vector env in an SB3-style loop (in
the empty room and in randomly furnished ones).

Writes results/bench.json and prints a table.
    python tools/bench.py
"""

from __future__ import annotations

import os
import platform
from pathlib import Path

from ssbl_pb.analysis.report import write_json
from ssbl_pb.cli import ArgumentParser, int_at_least, run
from ssbl_pb.files import check_output_path

ROOT = Path(__file__).resolve().parents[1]

TARGETS = {"world_step_per_s": ("world_step_per_s", 10_000), "env_step_per_s": ("env_step_per_s", 5_000)}


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench.json", help="results JSON")
    ap.add_argument("--steps", type=int_at_least(100), default=20_000, help="steps per stepping measurement")
    ap.add_argument("--frames", type=int_at_least(10), default=500, help="frames per rendering measurement")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    ap.add_argument("--episodes", type=int_at_least(0), default=200,
                    help="also time evaluating the shipped policy on this many episodes (0: skip; default 200)")
    args = ap.parse_args(argv)

    check_output_path(args.out, is_dir=False)
    if not args.all_cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    # lazy: torch, SB3 and the renderer (~3 s), which --help does without
    from ssbl_pb.bench.simulator import evaluation_seconds, people_frame_rates, simulator_rates

    r = simulator_rates(args.steps, args.frames)
    r.update(people_frame_rates(max(10, args.frames // 5)))  # 640x480 frames take ~0.15 s each
    r["camera_84_vs_raw"] = r["camera_fps_84"] / r["raw_render_fps_84"]
    r["env_vs_raw_step"] = r["env_step_per_s"] / r["raw_step_per_s"]
    r["env_furnished_vs_empty"] = r["env_furnished_step_per_s"] / r["env_step_per_s"]
    r["env_waypoints_vs_empty"] = r["env_furnished_waypoints_step_per_s"] / r["env_step_per_s"]
    if args.episodes:
        r.update(evaluation_seconds(args.episodes))
    r["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, one core used"
    write_json(args.out, r)
    checks = {"world_step_per_s >= 10000": r["world_step_per_s"] >= 10_000,
              "camera_fps_84 >= 80% of raw_render_fps_84": r["camera_84_vs_raw"] >= 0.8,
              "env_step_per_s >= 5000": r["env_step_per_s"] >= 5_000,
              "env_step_per_s >= 0.42 x raw_step_per_s": r["env_vs_raw_step"] >= 0.42,
              "env_furnished_step_per_s >= 0.8 x env_step_per_s": r["env_furnished_vs_empty"] >= 0.8,
              "... with waypoints (the shipped policy's env)": r["env_waypoints_vs_empty"] >= 0.8,
              "five bodies' frame time <= 2 x the proxies' (320x240)": r["people5_body_vs_proxy_time_320"] <= 2.0,
              "... and at 640x480": r["people5_body_vs_proxy_time_640"] <= 2.0}
    print(f"{'measure':24s} {'per second':>12s}")
    for k in ("raw_step_per_s", "raw_render_fps_84", "world_step_per_s", "camera_fps_84", "camera_fps_128",
              "env_step_per_s", "env_furnished_step_per_s", "env_furnished_waypoints_step_per_s",
              "batched_env_step_per_s"):
        print(f"{k:24s} {r[k]:12.0f}")
    for k in ("people5_fps_proxy_320", "people5_fps_body_320", "people5_fps_proxy_640", "people5_fps_body_640"):
        print(f"{k:24s} {r[k]:12.1f}")
    print(f"{'env_vs_raw_step':24s} {r['env_vs_raw_step']:12.3f}")
    for k in ("people5_body_vs_proxy_time_320", "people5_body_vs_proxy_time_640"):
        print(f"{k:24s} {r[k]:12.3f}")
    print(f"{'env_furnished_vs_empty':24s} {r['env_furnished_vs_empty']:12.3f}")
    print(f"{'env_waypoints_vs_empty':24s} {r['env_waypoints_vs_empty']:12.3f}")
    if args.episodes:
        print(f"evaluate {args.episodes} episodes of the shipped policy: {r['evaluate_cpu_s']:.1f} s CPU, "
              f"{r['evaluate_wall_s']:.1f} s wall")
    for k, ok in checks.items():
        print(f"{'PASS' if ok else 'MISS'}  {k}")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
