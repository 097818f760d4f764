#!/usr/bin/env python
"""Accuracy of the facing read from the virtual Pepper's camera frames (``ssbl_pb/perception/detection/facing.py``):
rendered QVGA frames of one person 1-5 m away and of an occluded pair, at facings uniform over 360 deg, and of
the env's groups, through deploy's colour detector (``ssbl_pb/bench/facing.py``). Writes OUT.json
(every sample and the summary) and OUT.md (tables of the error by true facing and distance) and prints the
Markdown.

    python tools/bench_facing.py                                # 3 x 400 frames (~40 s)
    python tools/bench_facing.py --frames 100 --out /tmp/facing
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.files import check_output_path, write_json, write_text
from ssbl_pb.perception.detection.proxy_facing import FacingParams

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int_at_least(1), default=400,
                    help="frames of each scene: one person, an occluded pair, a group (default 400)")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="scene seed (default 0)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_facing",
                    help="results stem: OUT.json and OUT.md (default results/bench_facing)")
    args = ap.parse_args(argv)
    for suffix in (".json", ".md"):
        check_output_path(args.out.with_suffix(suffix), is_dir=False)
    import numpy as np

    from ssbl_pb.bench.facing import markdown, run_bench, summarise  # lazy: the renderer and tracker, not for --help

    with progress_bar(3 * args.frames, "frames", "frame") as bar:
        samples, seconds = run_bench(args.frames, args.seed, progress=bar)
    command = "python tools/bench_facing.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None
                                                                                 else argv))
    summary = summarise(samples)
    ms = 1e3 * np.array(seconds)
    timing = {"median_ms": round(float(np.median(ms)), 2), "p90_ms": round(float(np.percentile(ms, 90)), 2)}
    write_json(args.out.with_suffix(".json"), {
        "command": command.strip(), "frames": args.frames, "seed": args.seed,
        "params": dataclasses.asdict(FacingParams()), "facing_time_per_frame": timing, "summary": summary,
        "samples": [dataclasses.asdict(s) for s in samples]})
    text = markdown(summary, command.strip())
    text += (f"\nestimate_facing per frame (all boxes, this machine): median {timing['median_ms']} ms, "
             f"p90 {timing['p90_ms']} ms\n")
    write_text(args.out.with_suffix(".md"), text)
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
