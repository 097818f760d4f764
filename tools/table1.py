#!/usr/bin/env python
"""Regenerate the paper's Table I: every state representation x network trained and evaluated alike.

Rows: Vector + LSTM (the 100 % reference), CameraOnly + SAEV/conv + FF/LSTM, CameraSpeed + SAEV/conv + LSTM,
the random policy (0 %), plus Vector + FF and CameraSpeed + SAEV + FF. Stage 1 collects frames and trains the
SAEV and conv autoencoders (skipped for checkpoints given with --saev / --conv); stage 2 trains and evaluates
each row for each seed. Writes DIR/table1.md and DIR/table1.json; every finished row is kept in DIR/rows/, so
running the same command again after an interruption resumes at the first unfinished row.

Examples:
    python tools/table1.py --budget smoke --seeds 1 --out results/table1_smoke      # a few minutes
    python tools/table1.py --budget full --seeds 1 --out results/table1             # hours; resumable
    python tools/table1.py --budget medium --seeds 1 --out results/table1_medium     # about 2 h
    python tools/table1.py --budget full --seeds 1 --out results/table1 --saev results/ae/saev/encoder.pt \\
        --conv results/ae/conv/encoder.pt --rows vector_lstm,random_policy,cameraspeed_saev_lstm
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, run


def main(argv: list[str] | None = None) -> int:
    from ssbl_pb.analysis.table1 import BUDGETS, ROWS

    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--budget", required=True, help=f"one of {', '.join(BUDGETS)}")
    ap.add_argument("--seeds", type=int, default=1, help="seeds per row (0 .. K-1; default 1)")
    ap.add_argument("--out", type=Path, required=True, help="output directory (reused to resume)")
    ap.add_argument("--rows", help=f"comma-separated subset of: {', '.join(r.slug for r in ROWS)}")
    ap.add_argument("--saev", help="a trained SAEV checkpoint (tools/train_ae.py) instead of training one")
    ap.add_argument("--conv", help="a trained conv AE checkpoint instead of training one")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    args = ap.parse_args(argv)

    from ssbl_pb.analysis.table1 import find_row, get_budget
    from ssbl_pb.errors import UserError
    from ssbl_pb.files import check_output_path
    from ssbl_pb.perception.ae_train import checkpoint_info

    budget = get_budget(args.budget)
    if args.seeds < 1:
        raise UserError(f"--seeds {args.seeds}: expected an integer >= 1")
    rows = [find_row(s) for s in args.rows.split(",")] if args.rows else list(ROWS)
    given = {"saev": args.saev, "conv": args.conv}
    for arch, path in given.items():
        if path and checkpoint_info(path)["arch"] != arch:
            raise UserError(f"--{arch} {path}: holds a {checkpoint_info(path)['arch']} autoencoder, not {arch}")
    check_output_path(args.out)

    import torch

    from ssbl_pb.analysis.table1 import prepare_encoders, run_row
    from ssbl_pb.analysis.table1_report import write_table
    from ssbl_pb.cli import make_bar

    torch.set_num_threads(max(1, args.threads))
    args.out.mkdir(parents=True, exist_ok=True)
    encoders = prepare_encoders(budget, args.out, {r.encoder for r in rows} & {"saev", "conv"}, given)
    bar = make_bar(len(rows) * args.seeds, "table I", "row")
    results = []
    try:
        for seed in range(args.seeds):
            for row in rows:
                bar.set_postfix_str(f"{row.label}, seed {seed}")
                results.append(run_row(row, seed, budget, args.out, encoders))
                bar.update(1)
    finally:
        bar.close()
    command = "python tools/table1.py " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    write_table(args.out, results, budget, command)
    print(f"{len(results)} row runs -> {args.out}/table1.md")
    return 0


if __name__ == "__main__":
    run(main)
