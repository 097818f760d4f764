#!/usr/bin/env python
"""Local pool throughput: the trials of a sweep spec run with one worker and with N (alternately, --repeats
times each), median trials per minute and the speed-up (target: >= 1.7x for 2 workers on 2 cores).
Writes OUT (JSON) and OUT with .md.

Examples:
    python tools/bench_sweep.py                                   # configs/sweeps/bench.yaml, 2 workers, 2 repeats
    python tools/bench_sweep.py --workers 4 --repeats 1 --out results/bench_sweep_4.json
"""

from __future__ import annotations

import sys
from pathlib import Path

from ssbl_pb.bench.sweep_pool import bench_pool, markdown
from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, write_json, write_text
from ssbl_pb.sweep import load_spec

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--spec", type=Path, default=ROOT / "configs" / "sweeps" / "bench.yaml", help="sweep spec")
    ap.add_argument("--workers", type=int_at_least(2), default=2, help="the pool compared with one worker (default 2)")
    ap.add_argument("--repeats", type=int_at_least(1), default=2, help="runs per setting (default 2)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_sweep.json", help="JSON result")
    args = ap.parse_args(argv)
    if args.out.suffix != ".json":
        raise UserError(f"--out {args.out}: expected a .json file name")

    spec = load_spec(args.spec)
    check_output_path(args.out, "--out", is_dir=False)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = bench_pool(spec, args.workers, args.repeats, args.out.parent,
                        note=lambda text: print(text, file=sys.stderr, flush=True))
    command = command_line("tools/bench_sweep.py", argv)
    write_json(args.out, result)
    write_text(args.out.with_suffix(".md"), markdown(result, command))
    print(f"speed-up {result['speedup']}x with {args.workers} workers "
          f"({'met' if result['speedup'] >= 1.7 or args.workers != 2 else 'MISSED'}: >= 1.7x for 2) -> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
