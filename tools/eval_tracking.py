"""Score tracks against ground-truth boxes: MOTA, IDF1, ID switches (motmetrics, IoU >= 0.5) and the
ground-plane position error (median, 90th percentile, metres) of matched pairs.

    python tools/eval_tracking.py --tracks results/tracking/pets \
        --gt ../shared/data/video/pets2009_s2l1/PETS2009-S2L1.xml \
        --calib ../shared/data/video/pets2009_s2l1/View_001_tsai_calibration.xml --range 0:400 --range 400:795

GT: CVML XML (.xml, PETS) or MOTChallenge text (.txt, 1-based frames). Track frames are 0-based internally.
Writes DIR/metrics.json and DIR/metrics.md (or --json/--md). Exit code 2 on bad input, writing nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.files import write_json, write_text
from ssbl_pb.perception.datasets.scoring import to_markdown
from ssbl_pb.perception.tracking.tracking_io import InputError, evaluate_dir


def parse_range(text: str) -> tuple[int, int | None]:
    try:
        a, b = text.split(":")
        start, stop = int(a or 0), (int(b) if b else None)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--range {text!r}: expected START:STOP (stop exclusive)") from exc
    if start < 0 or (stop is not None and stop <= start):
        raise argparse.ArgumentTypeError(f"--range {text!r}: expected 0 <= START < STOP")
    return start, stop


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--tracks", required=True, help="folder with tracks_mot.txt (and tracks_world.csv)")
    ap.add_argument("--gt", required=True, help="ground truth: PETS CVML .xml or MOTChallenge .txt")
    ap.add_argument("--calib", default=None, help="Tsai calibration XML for the ground-plane error")
    ap.add_argument("--range", dest="ranges", type=parse_range, action="append",
                    help="frame range START:STOP (0-based, stop exclusive); repeatable; default: all frames")
    ap.add_argument("--json", default=None, help="output JSON (default DIR/metrics.json)")
    ap.add_argument("--md", default=None, help="output Markdown (default DIR/metrics.md)")
    args = ap.parse_args(argv)
    try:
        res = evaluate_dir(args.tracks, args.gt, args.calib, args.ranges or [(0, None)])
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    d = Path(args.tracks)
    write_json(args.json or d / "metrics.json", res)
    write_text(args.md or d / "metrics.md", to_markdown(res, f"Tracking: {d}"))
    for name, r in res.items():
        print(f"{name}: MOTA {r['mota']:.3f}  IDF1 {r['idf1']:.3f}  IDsw {r['num_switches']:.0f}  "
              f"ground err median {r.get('ground_err_median_m', float('nan')):.3f} m "
              f"p90 {r.get('ground_err_p90_m', float('nan')):.3f} m")
    return 0


if __name__ == "__main__":
    run(main)
