#!/usr/bin/env python
"""Sweep training configurations x seeds: train each trial, evaluate it on held-out episodes, summarise each
configuration (mean and 95 % CI over seeds): DIR/summary.md, summary.csv, summary.png, trials.csv, trials/NAME/.

SPEC.yaml: base (a training config), grid (train_pb.py --set keys -> lists of values), seeds, optional set (fixed
overrides) and eval (episodes, seed, scenario, model, paths); see configs/sweeps/example.yaml.

Examples:
    python tools/sweep.py configs/sweeps/example.yaml --out results/sweep_example        # one worker per core
    python tools/sweep.py configs/sweeps/example.yaml --out results/sweep_example --dry-run   # list the trials
    python tools/sweep.py SPEC.yaml --out results/sw --address HEAD:6379 --storage /nfs/sweeps  # a Ray cluster

A killed sweep continues with the same command: finished trials are kept, unfinished ones start again from
scratch (so results do not depend on the interruption). Ray clusters: docs/scale-out.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, command_line, run
from ssbl_pb.files import output_dir, write_json
from ssbl_pb.sweep import finished, load_spec
from ssbl_pb.sweep.cli import TrialsRoot, add_run_options
from ssbl_pb.sweep.summary import write_summary


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("spec", type=Path, help="sweep spec (YAML)")
    ap.add_argument("--out", type=Path, required=True, help="output directory (summary; trials/ unless --storage)")
    add_run_options(ap)
    ap.add_argument("--dry-run", action="store_true", help="check the spec and list the trials; run nothing")
    args = ap.parse_args(argv)

    where = TrialsRoot(args)
    spec = load_spec(args.spec)
    trials = spec.trials()
    where.connect()
    root = where.path
    done = finished(root, trials)
    if args.dry_run:
        for t in trials:
            print(f"{'done   ' if t.name in done else 'pending'}  {root / 'trials' / t.name}")
        print(f"{len(trials)} trials ({len(spec.configs)} configurations x {len(spec.seeds)} seeds), "
              f"{len(done)} finished")
        return 0
    with output_dir(args.out, "--out") as out:
        write_json(out / "sweep.json", {**spec.describe(), "trials_root": str(root)})
    command = command_line("tools/sweep.py", argv)
    t0 = time.perf_counter()
    try:
        outcome = where.run(trials, "sweep")
    finally:
        records = finished(root, trials)
        if records:
            write_summary(args.out, spec, records, root, command)
        if len(records) < len(trials):
            print(f"{len(records)} of {len(trials)} trials finished; run the same command to continue",
                  file=sys.stderr)
    outcome.raise_failures(root)
    print(f"{len(trials)} trials ({len(spec.configs)} configurations x {len(spec.seeds)} seeds) in "
          f"{time.perf_counter() - t0:.0f} s -> {args.out}/summary.md")
    return 0


if __name__ == "__main__":
    run(main)
