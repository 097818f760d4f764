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
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ssbl_pb.cli import ArgumentParser, progress, run
from ssbl_pb.files import check_output_path, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]
PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"
DETECTORS = ("ssd", "movenet")  # HOG needs every frame in order (its background model learns): not here


def make(name: str) -> Any:
    """The detector ``name`` with its built-in settings (the SSD as tuned in ``PipelineParams``)."""
    if name == "ssd":
        from ssbl_pb.perception.detection.learned import SsdDetector
        from ssbl_pb.perception.tracking.tuning import PipelineParams

        return SsdDetector(PipelineParams().ssd)
    from ssbl_pb.perception.detection.movenet import MoveNetDetector

    return MoveNetDetector()


def coverage(detect: Any, video: Path, gt: np.ndarray, frames: range, paint: Any | None) -> dict[str, float]:
    """The counts above for one detector (``paint(i, frame)``: the feet-hidden frame, or None)."""
    from ssbl_pb.perception.datasets.occlusion import KEEP
    from ssbl_pb.perception.detection.learned import box_iou
    from ssbl_pb.perception.tracking.pipeline import read_frames

    people = boxes = upper = whole = either = 0
    ms = []
    wanted = set(frames)
    for i, frame in progress(read_frames(str(video), frames.start, frames.stop), "frames", "frame",
                             total=frames.stop - frames.start):
        if i not in wanted:
            continue
        f = paint(i, frame) if paint is not None else frame
        t = time.perf_counter()
        b = np.asarray(detect(f), dtype=float).reshape(-1, 5)
        ms.append(1e3 * (time.perf_counter() - t))
        g = gt[gt[:, 0] == i, 2:6]
        boxes += len(b)
        people += len(g)
        if not len(g) or not len(b):
            continue
        up = g.copy()
        up[:, 3] *= KEEP
        iu, iw = box_iou(up, b).max(axis=1), box_iou(g, b).max(axis=1)
        upper += int((iu >= 0.5).sum())
        whole += int((iw >= 0.5).sum())
        either += int((np.maximum(iu, iw) >= 0.3).sum())
    n = max(people, 1)
    return {"person_frames": people, "boxes": boxes, "upper_iou50": upper / n, "whole_iou50": whole / n,
            "either_iou30": either / n, "ms_median": float(np.median(ms)) if ms else float("nan")}


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
    from ssbl_pb.perception.datasets.occlusion import FeetHidden, median_background
    from ssbl_pb.perception.datasets.pets import load_ground_truth

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
    gt = load_ground_truth(args.gt)
    frames = range(start, stop, args.step)
    paint = FeetHidden(gt, median_background(str(args.video))) if args.hide_feet else None
    rows = {}
    for name in args.detector:
        detect = make(name)
        rows[name] = {"visible": coverage(detect, args.video, gt, frames, None)}
        if paint is not None:
            rows[name]["feet hidden"] = coverage(detect, args.video, gt, frames, paint)
    lines = [f"Detector coverage on {args.video.name} frames {start}-{stop - 1}, every {args.step}th (`python "
             f"tools/detector_coverage.py {' '.join(sys.argv[1:] if argv is None else argv)}`): the share of GT people "
             f"a box covers, before tracking.", "",
             "| detector | frames | people | boxes | upper body IoU>=0.5 | whole IoU>=0.5 | either IoU>=0.3 | ms |",
             "|---|---|---|---|---|---|---|---|"]
    for name, by in rows.items():
        for case, r in by.items():
            lines.append(f"| {name} | {case} | {r['person_frames']} | {r['boxes']} | {r['upper_iou50']:.3f} | "
                         f"{r['whole_iou50']:.3f} | {r['either_iou30']:.3f} | {r['ms_median']:.0f} |")
    write_json(args.out.with_suffix(".json"), rows)
    write_text(args.out.with_suffix(".md"), "\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    run(main)
