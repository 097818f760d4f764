"""Tracking benchmark: thresholds chosen on PETS S2L1 frames 0-399 only, then results on frames
400-794 and on the whole sequence; timings; the simulation evaluation.

    python tools/bench_tracking.py            # everything (about 25 min on 2 shared cores)
    python tools/bench_tracking.py --skip-tune --skip-sim

Steps: (1) one HOG pass over all frames at every candidate scale with a low SVM margin, cached (windows +
foreground fractions); (2) coordinate descent over the pipeline's thresholds scored by MOTA + IDF1 on frames
0-399 only, starting from untuned values; (3) tools/track.py's code path (online detector + tracker) over the
whole video with the chosen thresholds, scored on 400-794 and 0-794; (4) timings on one core; (5) the tracker
on first-person TinyRenderer frames against the simulator's member positions.
Writes results/tracking/{pets_params,pets_metrics,timing,sim,bench}.json, results/tracking/pets_s{stride}/
(tracks + overlay per variant) and docs/benchmarks_tracking.md.

    python tools/bench_tracking.py --compare  # HOG, the SSD and MoveNet, about 12 min on 2 shared cores

--compare runs each detector (HOG, SSD, MoveNet) with its built-in thresholds (chosen on frames 0-399) through
tools/track.py's code path on one thread (cv2.setNumThreads(1)): the whole video scored on 400-794, then frames
400-794 with every GT person's lower body painted over (--hide-feet); it writes results/tracking/compare.json and
the comparison table into docs/tracking.md (between the detector-comparison markers).

    python tools/bench_tracking.py --tune --detector ssd --input-size 400x300  # about 35 min on 2 shared cores

--tune chooses one detector's pipeline thresholds (detector, tracker, measurement noise per ranging cue) on frames
0-399 only: the detector runs once over frames 0-399 as they are and with the feet hidden (cached in
results/tracking/.cache), the SSD boxes' median offsets from the GT boxes are measured on them
(``learned.box_offsets``), then coordinate descent over ``PipelineParams.grid`` from the built-in values, scored by
MOTA + IDF1 on both versions (``--objective visible`` for the unpainted frames alone). It writes the chosen
values to results/tracking/{detector}_params.json (tools/track.py --params reads it; copy them into
``tuning.SSD_DEFAULT`` to make them the built-in ones) and reports frames 400-794 through tools/track.py's code
path on one thread (results/tracking/tune_{detector}.json).
"""

from __future__ import annotations

import json
from pathlib import Path

from ssbl_pb.bench.sim_tracking import SimEvalParams
from ssbl_pb.bench.tracking import DETECTORS, PETS, ROOT, compare, full, markdown, tune_detector
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import write_text


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--data", default=str(PETS), help="folder with vtest.avi, PETS2009-S2L1.xml, calibration")
    ap.add_argument("--out", default=str(ROOT / "results" / "tracking"), help="results folder")
    ap.add_argument("--doc", default=str(ROOT / "docs" / "benchmarks_tracking.md"), help="Markdown report")
    ap.add_argument("--skip-tune", action="store_true", help="use the built-in (previously tuned) thresholds")
    ap.add_argument("--skip-sim", action="store_true", help="skip the simulation evaluation")
    ap.add_argument("--strides", type=int, nargs="+", default=[8, 4],
                    help="HOG window strides to tune; the best MOTA + IDF1 on frames 0-399 is selected")
    ap.add_argument("--report-only", action="store_true",
                    help="re-render the Markdown from results/tracking/bench.json without running anything")
    ap.add_argument("--sim-episodes", type=int, default=SimEvalParams.episodes)
    ap.add_argument("--compare", action="store_true",
                    help="only the detector comparison (HOG, SSD, MoveNet; feet visible and hidden) -> "
                         "docs/tracking.md")
    ap.add_argument("--tracking-doc", default=str(ROOT / "docs" / "tracking.md"),
                    help="the page whose detector-comparison section --compare rewrites")
    ap.add_argument("--variant", action="append", default=[], metavar="LABEL=PARAMS.json",
                    help="--compare: one more row, the pipeline parameters in PARAMS.json (as --tune writes them)")
    ap.add_argument("--tune", action="store_true",
                    help="only choose --detector's thresholds on frames 0-399 and report 400-794 (see above)")
    ap.add_argument("--detector", choices=DETECTORS, default="ssd", help="the detector --tune tunes (default ssd)")
    ap.add_argument("--input-size", default=None, metavar="WxH",
                    help="--tune, ssd or movenet: the network's input size (default: the built-in one)")
    ap.add_argument("--objective", choices=("both", "visible"), default="both",
                    help="--tune: MOTA + IDF1 on frames 0-399 with the feet visible and hidden (both), or visible only")
    ap.add_argument("--init", choices=("default", "untuned"), default="default",
                    help="--tune: start from the built-in thresholds or from the untuned ones")
    ap.add_argument("--rounds", type=int, default=3, help="--tune: coordinate-descent rounds (at most)")
    args = ap.parse_args(argv)
    data, out = Path(args.data), Path(args.out)
    if args.tune:
        return tune_detector(data, out, args, argv)
    if args.compare:
        return compare(data, out, Path(args.tracking_doc), argv, args.variant)
    if args.report_only:
        if not (out / "bench.json").is_file():
            raise UserError(f"--report-only: no {out / 'bench.json'} (run the benchmark into --out first)")
        write_text(args.doc, markdown(json.loads((out / "bench.json").read_text())))
        return 0
    return full(data, out, Path(args.doc), args.skip_tune, args.skip_sim, args.strides, args.sim_episodes, argv)


if __name__ == "__main__":
    run(main)
