#!/usr/bin/env python
"""Benchmarks of the camera state representations: encoder frames/s, camera-mode training throughput against
the raw TinyRenderer frame rate, the autoencoders' training time and quality, a linear probe of the features
to the members' positions (SAEV vs conv), the keypoint precision that probe asks for, the features' jitter from
frame to frame (as encoded and low-passed, config feature_smoothing), and the SAEV keypoint detector in the
simulated tracker.

Writes OUT (JSON) and prints a Markdown summary (docs/benchmarks.md, "Camera state representations").

Examples:
    python tools/bench_camera.py --frames results/frames/frames.npz --saev results/ae/saev/encoder.pt \\
        --conv results/ae/conv/encoder.pt --out results/bench_camera.json
    python tools/bench_camera.py --only precision --frames results/frames/frames.npz --out results/precision.json
    python tools/bench_camera.py --only encoders --out results/bench_encoders.json
    python tools/bench_camera.py --only jitter --frames results/fov26/frames.npz \
        --saev results/fov26/ae/saev/encoder.pt --conv results/fov26/ae/conv/encoder.pt --out results/jitter.json
"""

from __future__ import annotations

import json
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, make_bar, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, write_json

PARTS = ("encoders", "throughput", "autoencoders", "probe", "precision", "jitter", "tracking", "pets")


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, required=True, help="output .json")
    ap.add_argument("--frames", type=Path, help="frames .npz (tools/collect_frames.py): probe, tracking")
    ap.add_argument("--saev", type=Path, help="SAEV checkpoint (tools/train_ae.py)")
    ap.add_argument("--conv", type=Path, help="conv AE checkpoint")
    ap.add_argument("--pets", type=Path, help="PETS 2009 S2L1 folder (vtest.avi, PETS2009-S2L1.xml, "
                    "View_001_tsai_calibration.xml): SAEV trained on frames 0-399, tracked on 400-794")
    ap.add_argument("--pets-steps", type=int, default=800, help="SAEV training steps on PETS (default 800)")
    ap.add_argument("--only", help=f"comma-separated parts: {', '.join(PARTS)} (default all)")
    ap.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    args = ap.parse_args(argv)

    from ssbl_pb.perception.autoencoding.ae_train import read_checkpoint  # lazy: torch (~2 s), not for --help

    parts = args.only.split(",") if args.only else list(PARTS)
    if bad := sorted(set(parts) - set(PARTS)):
        raise UserError(f"--only {args.only!r}: unknown part(s) {bad}; expected {list(PARTS)}")
    needs = {"throughput": ["saev"], "autoencoders": ["saev", "conv"], "probe": ["frames", "saev", "conv"],
             "precision": ["frames"], "jitter": ["frames", "saev", "conv"], "tracking": ["frames", "saev"],
             "pets": ["pets"]}
    for part in parts:
        for what in needs.get(part, []):
            if getattr(args, what) is None:
                raise UserError(f"--only {part} needs --{what}")
    for arch in ("saev", "conv"):
        if getattr(args, arch) is not None and read_checkpoint(getattr(args, arch))["arch"] != arch:
            raise UserError(f"--{arch} {getattr(args, arch)}: not a {arch} checkpoint")
    pets_files = ("vtest.avi", "PETS2009-S2L1.xml", "View_001_tsai_calibration.xml")
    if "pets" in parts and not all((args.pets / f).is_file() for f in pets_files):
        raise UserError(f"--pets {args.pets}: expected a folder holding {list(pets_files)}")
    check_output_path(args.out, "--out", is_dir=False)
    frames = None
    if args.frames is not None and {"probe", "precision", "jitter", "tracking"} & set(parts):
        from ssbl_pb.analysis.frames import load_frames  # lazy: the env, for these parts only

        frames = load_frames(args.frames, 64)

    import os

    import torch

    from ssbl_pb.bench import camera as cb  # lazy: torch and SB3, not for --help

    torch.set_num_threads(args.threads)
    res: dict = {"threads": args.threads, "load_average_at_start": [round(v, 2) for v in os.getloadavg()]}
    if "encoders" in parts:
        res["encoder_fps_batch64"] = {f"{a}/{s}": round(cb.encoder_fps(a, s)) for a in ("saev", "conv")
                                      for s in ("cpu", "paper")}
    if "throughput" in parts:
        res["render_fps_64"] = round(cb.render_fps(64))
        res["train_steps_per_s"] = {p: round(cb.training_throughput(str(args.saev), policy=p)) for p in ("ff",)}
        res["train_vs_render"] = round(res["train_steps_per_s"]["ff"] / res["render_fps_64"], 3)
    if "autoencoders" in parts:
        res["autoencoders"] = {a: read_checkpoint(getattr(args, a))["extra"].get("summary", {})
                               for a in ("saev", "conv")}
    if "probe" in parts:
        res["probe"] = cb.probe_encoders(frames, {"saev": str(args.saev), "conv": str(args.conv)})
    if "precision" in parts:
        res["precision"] = cb.keypoint_precision(frames)
    if "jitter" in parts:
        res["jitter"] = cb.feature_jitter(frames, {"saev": str(args.saev), "conv": str(args.conv)})
    if "tracking" in parts:
        res["tracking_saev"] = cb.keypoint_tracking(frames, str(args.saev))
    if "pets" in parts:
        # lazy: optional, PETS scoring needs motmetrics (the tracking extra)
        from ssbl_pb.perception.autoencoding.pets_saev import pets_saev

        bar = make_bar(args.pets_steps, "SAEV on PETS", "step")
        res["pets_saev"] = pets_saev(*(args.pets / f for f in pets_files), steps=args.pets_steps, progress=bar)
        bar.close()
    write_json(args.out, res)
    print(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    run(main)
