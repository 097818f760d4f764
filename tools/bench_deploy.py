#!/usr/bin/env python
"""Deploy against the virtual Pepper over qi, in real time: seeded approaches scored by ground truth, the fault
timings and a soak. Writes OUT.json and OUT.md (the docs/benchmarks.md section) and keeps every run's logs.

    python tools/bench_deploy.py                                   # 20 runs, all faults, a 600 s soak (~25 min)
    python tools/bench_deploy.py --runs 3 --faults sigint --soak 60 --out results/bench_deploy_quick
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.env.layouts import GROUP_MODELS
from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from ssbl_pb.deploy.bench import FAULTS

    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int_at_least(0), default=20, help="seeded approaches (default 20)")
    ap.add_argument("--seed", type=int, default=500_000, help="first held-out seed")
    ap.add_argument("--scenario", default="default", help="the virtual Pepper's scenario (default: the paper's)")
    ap.add_argument("--policy", default="vector", help="the policy deploy runs (default: the shipped vector)")
    ap.add_argument("--groups", choices=GROUP_MODELS, help="the group model of the virtual Pepper and deploy "
                    "(default: the policy's, its config's env.groups)")
    ap.add_argument("--faults", default=",".join(FAULTS), help=f"comma list of {', '.join(FAULTS)}, or none")
    ap.add_argument("--soak", type=float, default=600.0, help="soak seconds (0: none)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_deploy",
                    help="results stem: OUT.json, OUT.md and the runs' logs in OUT/")
    args = ap.parse_args(argv)
    faults = [] if args.faults == "none" else args.faults.split(",")
    bad = sorted(set(faults) - set(FAULTS))
    if bad:
        raise UserError(f"--faults {','.join(bad)}: expected a comma list of {', '.join(FAULTS)}, or none")
    if args.soak < 0:
        raise UserError(f"--soak {args.soak}: expected seconds >= 0")
    from ssbl_pb.analysis.evaluation import check_policy_spec
    from ssbl_pb.files import check_output_path

    check_policy_spec(args.policy)
    if args.groups is None:
        from ssbl_pb.deploy.group import policy_groups

        args.groups = policy_groups(args.policy)
    check_output_path(args.out.with_suffix(".json"), is_dir=False)

    from ssbl_pb.deploy.bench import environment, markdown, run_approach, run_fault, soak
    from ssbl_pb.files import write_json, write_text

    logs = args.out.with_suffix("")
    shutil.rmtree(logs, ignore_errors=True)
    res = {"environment": environment(), "scenario": args.scenario, "policy": args.policy, "groups": args.groups,
           "approaches": [],
           "faults": []}
    with progress_bar(args.runs, "approaches", "run") as bar:
        for i in range(args.runs):
            res["approaches"].append(run_approach(logs / f"run{i:02d}", args.seed + i, args.policy, args.scenario,
                                                   groups=args.groups))
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
