#!/usr/bin/env python
"""Train a camera autoencoder (paper III-B: conv or SAEV) on frames from tools/collect_frames.py.

Writes DIR/encoder.pt (architecture, size and input resolution recorded; checked when loaded), history.csv,
losses.png, reconstructions.png, keypoints.png (SAEV: keypoints drawn on held-out frames, one colour each,
as the paper's Fig. 7) and summary.json.

Examples:
    python tools/train_ae.py --frames results/frames/frames.npz --arch saev --out results/ae/saev
    python tools/train_ae.py --frames frames.npz --arch conv --steps 500 --out results/ae/conv_quick
    python tools/train_ae.py --frames frames96.npz --arch saev --size paper --out results/ae/saev_paper
    python tools/train_ae.py --frames frames.npz --arch saev --smoothness-weight 0.05 --out results/ae/saev_steady
    python tools/train_ae.py --frames frames.npz --arch saev --steps 16000 --snapshot-every 2000 --out results/ae/long
    python tools/train_ae.py --frames frames.npz --arch saev --steps 16000 --snapshot-every 2000 --out results/ae/long \
        --resume results/ae/long/snapshots/encoder_step6000.pt
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import torch

from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, make_bar, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, output_dir
from ssbl_pb.perception.autoencoding.ae_losses import LossWeights
from ssbl_pb.perception.autoencoding.ae_train import (
    AETrainParams,
    checkpoint_info,
    resume_state,
    save_checkpoint,
    split_centres,
    train_autoencoder,
)
from ssbl_pb.perception.autoencoding.autoencoders import ARCHS, DEFAULT_SIZE, SIZES, build, get_size


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=Path, required=True, help=".npz from tools/collect_frames.py")
    ap.add_argument("--arch", required=True, help=f"one of {', '.join(ARCHS)}")
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    ap.add_argument("--size", default=DEFAULT_SIZE, help=f"layer sizes: {', '.join(SIZES)} (default {DEFAULT_SIZE})")
    ap.add_argument("--steps", type=int, default=3000, help="optimiser steps (default 3000)")
    ap.add_argument("--batch", type=int, default=32, help="frame triplets per step (default 32)")
    ap.add_argument("--lr", type=float, default=1e-3, help="Adam learning rate (default 1e-3)")
    ap.add_argument("--smoothness-weight", type=float, metavar="W",
                    help="weight of Finn's smoothness loss, the keypoints' (SAEV) or code's (conv) squared second "
                         "difference over consecutive frames (default 0.001, the original's; "
                         "larger: steadier features)")
    ap.add_argument("--seed", type=int_at_least(0), default=0)
    ap.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    ap.add_argument("--snapshot-every", type=int, default=0, metavar="N",
                    help="also write DIR/snapshots/encoder_stepN.pt every N steps (a multiple of the evaluation "
                         "interval, min(250, steps/10)), for a learning curve of tools/bench_camera.py; kept if "
                         "the run is interrupted; 0: none")
    ap.add_argument("--resume", type=Path, metavar="SNAPSHOT",
                    help="continue an interrupted run from one of its snapshots (same frames, arch, size, batch, "
                         "lr, seed, smoothness weight and --snapshot-every steps' evaluation interval): the result "
                         "is that of an uninterrupted run")
    args = ap.parse_args(argv)

    # lazy: the env and the renderer (~1.4 s on top of torch), which --help does without
    from ssbl_pb.analysis.ae_report import write_report
    from ssbl_pb.analysis.frames import FramesError, load_frames  # lazy: as above

    model_size = build(args.arch, args.size).size.name  # unknown arch / size: exit 2 before reading anything
    params = AETrainParams(steps=args.steps, batch=args.batch, lr=args.lr, seed=args.seed,
                           eval_every=max(1, min(250, args.steps // 10)),
                           weights=LossWeights() if args.smoothness_weight is None
                           else LossWeights(smoothness=args.smoothness_weight))
    if args.snapshot_every < 0 or args.snapshot_every % params.eval_every:
        raise UserError(f"--snapshot-every {args.snapshot_every}: expected 0 or a multiple of the evaluation "
                        f"interval {params.eval_every}")
    if args.resume:  # a missing or foreign snapshot fails before the frames are read
        if "resume" not in checkpoint_info(args.resume, "--resume")["extra"]:
            raise UserError(f"--resume {args.resume}: holds no training state (a snapshot of --snapshot-every does)")
    data = load_frames(args.frames, get_size(args.size).input_size)
    try:  # enough episodes to hold some out for validation
        split_centres(data["episode"], params.val_every_episode)
    except UserError as exc:
        raise FramesError(f"--frames {args.frames}: {exc}") from exc
    resumed_at = 0
    if args.resume:  # the snapshot continues this run (settings, frames): checked before any output
        resumed_at = int(resume_state(args.resume, args.arch, model_size, params, len(data["frames"]))["step"])

    torch.set_num_threads(max(1, args.threads))
    created, snapshots = not args.out.exists(), []
    if args.snapshot_every:  # DIR made here, so output_dir keeps it (and the snapshots) when interrupted
        check_output_path(args.out).mkdir(parents=True, exist_ok=True)
    try:
        with output_dir(args.out) as out:
            def snapshot(step: int, model, state: dict) -> None:
                if args.snapshot_every and step % args.snapshot_every == 0:
                    snapshots.append(save_checkpoint(out / "snapshots" / f"encoder_step{step}.pt", model,
                                                     {"step": step, "resume": state}))

            bar = make_bar(params.steps, f"train {args.arch}", "step", initial=resumed_at)
            try:
                model, history = train_autoencoder(data, args.arch, args.size, params, bar, on_eval=snapshot,
                                                   resume=args.resume)
            finally:
                bar.close()
            summary = write_report(out, model, history, data, {"frames_file": str(args.frames), "lr": args.lr,
                                                                "batch": args.batch, "seed": args.seed,
                                                                "smoothness_weight": params.weights.smoothness})
    except BaseException:
        if snapshots:
            print(f"snapshots kept: {snapshots[-1].parent} (last {snapshots[-1].name}); no encoder.pt; continue "
                  f"with: {resume_command(argv, snapshots[-1])}", file=sys.stderr)
        elif created:
            shutil.rmtree(args.out, ignore_errors=True)
        raise
    last = summary["final_val"]
    print(f"{args.arch} ({args.size}) {params.steps} steps in {summary['train_seconds']:.0f} s: validation "
          f"reconstruction {last['reconstruction']:.4f} -> {args.out}/encoder.pt")
    return 0


def resume_command(argv: list[str] | None, snapshot: Path) -> str:
    """This command line with ``--resume SNAPSHOT`` in place of any ``--resume`` it had."""
    args, out, skip = list(sys.argv[1:] if argv is None else argv), [], False
    for a in args:
        if skip:
            skip = False
        elif a == "--resume":
            skip = True
        elif not a.startswith("--resume="):
            out.append(a)
    return command_line("tools/train_ae.py", [*out, "--resume", str(snapshot)])


if __name__ == "__main__":
    run(main)
