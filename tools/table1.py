#!/usr/bin/env python
"""Regenerate the paper's Table I: every state representation x network trained and evaluated alike.

Rows: Vector + LSTM (the 100 % reference), CameraOnly + SAEV/conv + FF/LSTM, CameraSpeed + SAEV/conv + LSTM,
the random policy (0 %), plus Vector + FF and CameraSpeed + SAEV + FF. Stage 1 collects frames and trains the
SAEV and conv autoencoders (skipped for checkpoints given with --saev / --conv); stage 2 trains and evaluates
each row for each seed as a trial of the sweeps' machinery (tools/sweep.py): on a local process pool (--workers,
default one per core) or, with --address, as Ray Tune trials on a cluster (docs/scale-out.md). Writes
DIR/table1.md and DIR/table1.json; every row's run is DIR/trials/ROW,seed=S/ (its result.json marks it
finished), logs in DIR/logs/, so running the same command again after an interruption runs only unfinished rows.
The camera rows see through the paper's 26.5 deg camera (--camera-hfov; encoders given must have learned through
the same: tools/collect_frames.py --camera-hfov 26.5, then tools/train_ae.py).

Examples:
    python tools/table1.py --budget smoke --seeds 1 --out results/table1_smoke      # a few minutes
    python tools/table1.py --budget full --seeds 3 --out /nfs/table1 --address HEAD:6379   # rows on a cluster
    python tools/table1.py --budget full --seeds 1 --out results/table1             # hours; resumable
    python tools/table1.py --budget medium --seeds 1 --out results/table1_medium     # about 2 h
    python tools/table1.py --budget full --seeds 1 --out results/table1 --saev results/fov26/ae/saev/encoder.pt \\
        --conv results/fov26/ae/conv/encoder.pt --rows vector_lstm,random_policy,cameraspeed_saev_lstm
    python tools/table1.py --budget full --seeds 2 --out results/table1_pepper --camera-hfov 56.3   # Pepper's camera
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.table1_rows import BUDGETS, ROWS, TABLE_CAMERA_HFOV, TABLE_FEATURE_SMOOTHING
from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, run
from ssbl_pb.errors import UserError
from ssbl_pb.sweep import finished
from ssbl_pb.sweep.cli import TrialsRoot, add_run_options


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--budget", required=True, help=f"one of {', '.join(BUDGETS)}")
    ap.add_argument("--seeds", type=int, default=1, help="seeds per row (0 .. K-1; default 1)")
    ap.add_argument("--out", type=Path, required=True, help="output directory (reused to resume)")
    ap.add_argument("--rows", help=f"comma-separated subset of: {', '.join(r.slug for r in ROWS)}")
    ap.add_argument("--saev", help="a trained SAEV checkpoint (tools/train_ae.py) instead of training one")
    ap.add_argument("--conv", help="a trained conv AE checkpoint instead of training one")
    ap.add_argument("--camera-hfov", type=float, default=TABLE_CAMERA_HFOV, metavar="DEG",
                    help="the camera rows' field of view, degrees, for the frames the encoders learn from (default "
                         f"{TABLE_CAMERA_HFOV:g}, the paper's Unity camera; Pepper's own: 56.3); given encoders must "
                         "have learned through it")
    ap.add_argument("--feature-smoothing", type=float, default=TABLE_FEATURE_SMOOTHING, metavar="ALPHA",
                    help="low-pass of the camera rows' encoded features over each episode, the newest frame's "
                         f"weight in (0, 1] (default {TABLE_FEATURE_SMOOTHING:g}; 1: off, the paper's raw features; "
                         "docs/decisions.md, 'A low-pass on the encoded features')")
    ap.add_argument("--threads", type=int_at_least(1), default=1, help="torch threads per trial (default 1)")
    add_run_options(ap)
    args = ap.parse_args(argv)

    # lazy: torch, SB3 and the env (~3 s), which --help does without
    from ssbl_pb.analysis.frames import check_hfov
    from ssbl_pb.analysis.table1 import check_given_encoders, find_row, get_budget  # lazy: as above
    from ssbl_pb.env.gymenv.encoded import check_feature_smoothing  # lazy: as above

    budget = get_budget(args.budget)
    if args.seeds < 1:
        raise UserError(f"--seeds {args.seeds}: expected an integer >= 1")
    check_hfov(args.camera_hfov)
    check_feature_smoothing(args.feature_smoothing, "--feature-smoothing")
    rows = [find_row(s) for s in args.rows.split(",")] if args.rows else list(ROWS)
    given = {"saev": args.saev, "conv": args.conv}
    check_given_encoders(given, args.camera_hfov)  # before --out exists
    where = TrialsRoot(args)
    where.connect()

    import torch

    from ssbl_pb.analysis.table1 import prepare_encoders, row_trials  # lazy: as above
    from ssbl_pb.analysis.table1_report import write_table  # lazy: as above

    torch.set_num_threads(args.threads)
    args.out.mkdir(parents=True, exist_ok=True)
    # stage 1 beside the trials: on a cluster, every node reads the encoders from there
    encoders = prepare_encoders(budget, where.path, {r.encoder for r in rows} & {"saev", "conv"}, given,
                                camera_hfov_deg=args.camera_hfov)
    trials = row_trials(rows, args.seeds, budget, encoders, args.threads, args.feature_smoothing)
    try:
        outcome = where.run(trials, "table I")
    finally:
        results = [r["result"] for r in finished(where.path, trials).values()]
        if results:
            write_table(args.out, results, budget, command_line("tools/table1.py", argv))
    outcome.raise_failures(where.path)
    print(f"{len(results)} row runs -> {args.out}/table1.md")
    return 0


if __name__ == "__main__":
    run(main)
