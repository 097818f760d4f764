#!/usr/bin/env python
"""Deploy against the virtual Pepper over qi, in real time: seeded approaches scored by ground truth, the fault
timings and a soak. Writes OUT.json and OUT.md (the docs/benchmarks.md section) and keeps every run's logs.

    python tools/bench_deploy.py                                   # 20 runs, all faults, a 600 s soak (~25 min)
    python tools/bench_deploy.py --runs 3 --faults sigint --soak 60 --out results/bench_deploy_quick

The runs' logs go to the folder OUT/ (OUT without its suffix). A rerun replaces the runs it wrote there before
(the folder carries a ``.bench_deploy`` marker) and nothing else; a folder it did not write is refused.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, float_in, int_at_least, progress_bar, run
from ssbl_pb.env.layouts import GROUP_MODELS
from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]
MARKER = ".bench_deploy"  # in OUT/: this tool wrote the folder, so a rerun may replace its runs


def _written_before(logs: Path) -> list[Path]:
    """What an earlier run of this tool left in ``logs`` (to replace); refuses a folder it did not write."""
    if not logs.is_dir() or not any(logs.iterdir()):
        return []
    if not (logs / MARKER).is_file():
        raise UserError(f"--out: {logs}/ holds files this tool did not write (no {MARKER} marker); choose another "
                        f"--out or move them away")
    return [p for p in logs.iterdir() if p.name == MARKER or p.name == "soak" or p.name.startswith(("run", "fault_"))]


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
    ap.add_argument("--soak", type=float_in(0.0, 86400.0), default=600.0, help="soak seconds (0: none)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_deploy",
                    help="results stem: OUT.json, OUT.md and the runs' logs in OUT/")
    args = ap.parse_args(argv)
    faults = [] if args.faults == "none" else args.faults.split(",")
    bad = sorted(set(faults) - set(FAULTS))
    if bad:
        raise UserError(f"--faults {','.join(bad)}: expected a comma list of {', '.join(FAULTS)}, or none")
    from ssbl_pb.analysis.evaluation import check_policy_spec
    from ssbl_pb.env.scenarios import ScenarioMix
    from ssbl_pb.files import check_output_path

    ScenarioMix(args.scenario)  # a bad name fails here, before any folder exists
    check_policy_spec(args.policy)
    if args.groups is None:
        from ssbl_pb.deploy.group import policy_groups

        args.groups = policy_groups(args.policy)
    check_output_path(args.out.with_suffix(".json"), is_dir=False)
    check_output_path(args.out.with_suffix(".md"), is_dir=False)
    logs = args.out.with_suffix("")
    check_output_path(logs)
    written = _written_before(logs)

    from ssbl_pb.deploy.bench import environment, markdown, run_approach, run_fault, soak
    from ssbl_pb.files import write_json, write_text

    for old in written:  # the runs of an earlier benchmark into the same folder, and only those
        shutil.rmtree(old) if old.is_dir() else old.unlink()
    logs.mkdir(parents=True, exist_ok=True)
    (logs / MARKER).write_text("runs of tools/bench_deploy.py; a rerun replaces them\n")
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
