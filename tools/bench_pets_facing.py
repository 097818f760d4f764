#!/usr/bin/env python
"""Facing from MoveNet's keypoints on PETS S2L1 (``ssbl_pb/bench/pets_facing.py``): tools/track.py's code path
(detector, keypoint ranging, tracker, each track's facing) over frames START-STOP and over a copy of them played
backwards; each track's facing_deg against the walking direction of the ground-truth person it follows (those
walking at 0.5 m/s or more), the reversed copy against the forward walking direction (the facing must not flip
with the motion). Writes OUT.json (summary, every error, the runs' timings) and OUT.md, and prints the Markdown.

    python tools/bench_pets_facing.py                          # frames 400-794, ~3 min on a shared 2-core machine
    python tools/bench_pets_facing.py --start 0 --stop 400 --out results/tracking/facing_pets_0-399

Exit code 2 on bad input (the data folder, the frame range, the output path), with one line naming it.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import cv2

from ssbl_pb.bench.pets_facing import markdown
from ssbl_pb.bench.pets_facing import run as run_bench
from ssbl_pb.cli import ArgumentParser, command_line, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, source_commit, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]
PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"
PETS_FPS = 7.0  # PETS 2009 frame rate (vtest.avi's header says 10; tools/bench_tracking.py)


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--data", default=str(PETS), help="folder with vtest.avi, PETS2009-S2L1.xml and the calibration")
    ap.add_argument("--start", type=int, default=400, help="first frame (default 400: frames 0-399 chose the "
                                                           "settings)")
    ap.add_argument("--stop", type=int, default=795, help="last frame + 1 (default 795, the video's end)")
    ap.add_argument("--params", default=None, help="pipeline parameters JSON (as tools/track.py --params)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "tracking" / "facing_pets",
                    help="results stem: OUT.json and OUT.md (default results/tracking/facing_pets)")
    args = ap.parse_args(argv)

    data = Path(args.data)
    video, gt, calib = data / "vtest.avi", data / "PETS2009-S2L1.xml", data / "View_001_tsai_calibration.xml"
    for f in (video, gt, calib):
        if not f.is_file():
            print(f"error: {f}: not found (the PETS data lives in ../shared/data/video)", file=sys.stderr)
            return 2
    if not 0 <= args.start < args.stop:
        raise UserError(f"--start {args.start} --stop {args.stop}: expected 0 <= start < stop")
    params = None
    if args.params is not None:
        try:
            params = json.loads(Path(args.params).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise UserError(f"--params {args.params}: cannot read pipeline parameters as JSON ({exc})") from exc
    for suffix in (".json", ".md"):
        check_output_path(args.out.with_suffix(suffix), is_dir=False)
    cv2.setNumThreads(1)  # tools/track.py's timing: one core
    t0 = time.time()
    report = run_bench(video, calib, gt, args.start, args.stop, PETS_FPS, params)
    report.update({"command": command_line("tools/bench_pets_facing.py", argv), "commit": source_commit(),
                   "date": time.strftime("%Y-%m-%d %H:%M"), "start": args.start,
                   "stop": args.start + report["forward"]["run"]["frames"], "seconds": round(time.time() - t0)})
    write_json(args.out.with_suffix(".json"), report)
    text = markdown(report)
    write_text(args.out.with_suffix(".md"), text)
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
