#!/usr/bin/env python
"""Deploy against the virtual Pepper over qi, in real time: seeded approaches scored by ground truth, the fault
timings and a soak. Writes OUT.json and OUT.md (the docs/benchmarks.md section) and keeps every run's logs.

    python tools/bench_deploy.py                                   # 20 runs, all faults, a 600 s soak (~25 min)
    python tools/bench_deploy.py --runs 3 --faults sigint --soak 60 --out results/bench_deploy_quick
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from ssbl_pb.cli import progress_bar, run
from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from ssbl_pb.deploy.bench import FAULTS

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=20, help="seeded approaches (default 20)")
    ap.add_argument("--seed", type=int, default=500_000, help="first held-out seed")
    ap.add_argument("--scenario", default="default", help="the virtual Pepper's scenario (default: the paper's)")
    ap.add_argument("--policy", default="vector")
    ap.add_argument("--faults", default=",".join(FAULTS), help=f"comma list of {', '.join(FAULTS)}, or none")
    ap.add_argument("--soak", type=float, default=600.0, help="soak seconds (0: none)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_deploy")
    args = ap.parse_args(argv)
    faults = [] if args.faults == "none" else args.faults.split(",")
    bad = sorted(set(faults) - set(FAULTS))
    if bad or args.runs < 0 or args.soak < 0:
        raise UserError(f"--faults {bad} / --runs {args.runs} / --soak {args.soak}: expected faults among "
                        f"{list(FAULTS)} and counts >= 0")

    from ssbl_pb.deploy.bench import environment, markdown, run_approach, run_fault, soak
    from ssbl_pb.files import write_json, write_text

    logs = args.out.with_suffix("")
    shutil.rmtree(logs, ignore_errors=True)
    res = {"environment": environment(), "scenario": args.scenario, "policy": args.policy, "approaches": [],
           "faults": []}
    with progress_bar(args.runs, "approaches", "run") as bar:
        for i in range(args.runs):
            res["approaches"].append(run_approach(logs / f"run{i:02d}", args.seed + i, args.policy, args.scenario))
            bar(1)
    for f in faults:
        res["faults"].append(run_fault(f, logs / f"fault_{f}"))
    if args.soak > 0:
        res["soak"] = soak(logs / "soak", args.soak, args.seed, args.policy)
    write_json(args.out.with_suffix(".json"), res)
    text = markdown(res)
    write_text(args.out.with_suffix(".md"), text)
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
