"""How many ground-truth people a person detector's boxes cover, frame by frame, before any tracking: with the feet
in view, and with each person's lower body (below 55 % of its box) painted with the video's median background
(`--hide-feet`, as `tools/bench_tracking.py` does). Compares detectors' raw reach on real people; thresholds are
the detectors' own (no tuning).

    python tools/detector_coverage.py --detector ssd movenet --hide-feet --step 10

Counts, over the frames of --range (every --step-th): GT person-frames; boxes; the share of people whose visible
box (the upper body when hidden) a box overlaps with IoU >= 0.5, whose whole box one does, and whose upper or whole
box one overlaps with IoU >= 0.3; the median detector time (one thread). Writes OUT.json and OUT.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2

from ssbl_pb.bench.detector_coverage import DETECTORS, markdown, measure
from ssbl_pb.cli import ArgumentParser, command_line, run
from ssbl_pb.files import check_output_path, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]
PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--detector", nargs="+", choices=DETECTORS, default=["ssd", "movenet"])
    ap.add_argument("--video", type=Path, default=PETS / "vtest.avi")
    ap.add_argument("--gt", type=Path, default=PETS / "PETS2009-S2L1.xml", help="PETS CVML ground truth")
    ap.add_argument("--range", default="400:795", help="frames START:STOP (default 400:795, the held-out half)")
    ap.add_argument("--step", type=int, default=10, help="every STEP-th frame (default 10)")
    ap.add_argument("--hide-feet", action="store_true", help="also measure with the lower bodies painted over")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "tracking" / "detector_coverage",
                    help="output stem: OUT.json, OUT.md")
    args = ap.parse_args(argv)
    try:
        start, stop = (int(x) for x in args.range.split(":"))
    except ValueError:
        start = stop = -1
    if not (0 <= start < stop and args.step >= 1):
        print(f"error: --range {args.range!r} / --step {args.step}: expected START:STOP with 0 <= START < STOP and "
              f"STEP >= 1", file=sys.stderr)
        return 2
    for suffix in (".json", ".md"):  # before minutes of detection
        check_output_path(args.out.with_suffix(suffix), is_dir=False)
    for p in (args.video, args.gt):
        if not p.is_file():
            print(f"error: {p}: not found", file=sys.stderr)
            return 2
    cv2.setNumThreads(1)
    frames = range(start, stop, args.step)
    rows = measure(args.detector, args.video, args.gt, frames, args.hide_feet)
    text = markdown(rows, args.video, frames, command_line("tools/detector_coverage.py", argv))
    write_json(args.out.with_suffix(".json"), rows)
    write_text(args.out.with_suffix(".md"), text)
    print(text, end="")
    return 0


if __name__ == "__main__":
    run(main)
