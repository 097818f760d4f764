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

from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, make_bar, run
from ssbl_pb.errors import UserError


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("spec", type=Path, help="sweep spec (YAML)")
    ap.add_argument("--out", type=Path, required=True, help="output directory (summary; trials/ unless --storage)")
    ap.add_argument("--workers", type=int_at_least(1),
                    help="trials at once: local processes (default: one per core); with --address, a cap (default "
                         "none: one trial per CPU of the cluster)")
    ap.add_argument("--address", help="run on the Ray cluster at HOST:PORT (its head) or 'auto' (the cluster this "
                                      "machine belongs to); without it, a local process pool and no Ray")
    ap.add_argument("--storage", type=Path, help="with --address: a folder every node sees; trials go to "
                                                 "STORAGE/<--out's name>/ (default: --out itself, which then must be "
                                                 "shared)")
    ap.add_argument("--dry-run", action="store_true", help="check the spec and list the trials; run nothing")
    args = ap.parse_args(argv)

    from ssbl_pb.files import check_output_path, output_dir, write_json
    from ssbl_pb.sweep import finished, load_spec, run_trials
    from ssbl_pb.sweep.summary import write_summary

    if args.storage is not None and args.address is None:
        raise UserError(f"--storage {args.storage}: only with --address (a local sweep writes into --out)")
    check_output_path(args.out, "--out")
    root = args.out
    probe = None
    if args.address is not None:
        if args.storage is not None:
            check_output_path(args.storage, "--storage")
            root = args.storage / args.out.resolve().name
        from ssbl_pb.sweep.ray_runner import Probe, connect

        probe = Probe(args.address)  # a child process tries the cluster while the spec is checked
    spec = load_spec(args.spec)
    trials = spec.trials()
    if probe is not None:
        connect(args.address, probe)
    root = root.resolve()
    done = finished(root, trials)
    if args.dry_run:
        for t in trials:
            print(f"{'done   ' if t.name in done else 'pending'}  {root / 'trials' / t.name}")
        print(f"{len(trials)} trials ({len(spec.configs)} configurations x {len(spec.seeds)} seeds), "
              f"{len(done)} finished")
        return 0
    with output_dir(args.out, "--out") as out:
        write_json(out / "sweep.json", {**spec.describe(), "trials_root": str(root)})
    root.mkdir(parents=True, exist_ok=True)
    command = command_line("tools/sweep.py", argv)
    bar = make_bar(len(trials), "sweep", "trial", initial=len(done))
    t0 = time.perf_counter()

    def on_done(name: str, record: dict | None) -> None:
        bar.set_postfix_str(f"{name}: {'done' if record else 'FAILED'}")
        bar.update(1)

    try:
        outcome = run_trials(trials, root, args.workers, args.address, on_done)
    finally:
        bar.close()
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
