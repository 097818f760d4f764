#!/usr/bin/env python
"""Deploy against the virtual Pepper over qi, in real time: seeded approaches scored by ground truth, the fault
timings and a soak. Writes OUT.json and OUT.md (the docs/benchmarks.md section) and keeps every run's logs.

    python tools/bench_deploy.py                                   # 20 runs, all faults, a 600 s soak (~25 min)
    python tools/bench_deploy.py --runs 3 --faults sigint --soak 60 --out results/bench_deploy_quick
    python tools/bench_deploy.py --scenario mixed --runs 10 --faults none --soak 0 --lockstep --out /tmp/bd
    python tools/bench_deploy.py --scenario mixed --runs 5 --faults none --soak 0 --lockstep --appearance body

The virtual Pepper's people are box proxies (the colour detector's chain) unless ``--appearance body`` draws them
as bodies, which deploy's ``--detector auto`` then finds with MoveNet (over qi and in lockstep alike).

Every approach is also scored for perception against the virtual Pepper's ground truth, tick by tick
(``ssbl_pb/bench/perception_errors.py``): member position and velocity errors against distance, members
missed (out of view, at the image's edge, occluded, not detected), tracked twice, track ids per member, the group
centre, o-space radius and free slot errors, and how far the policy network's action moves between the perceived
and the true observation; per run and pooled in OUT.json, a table in OUT.md and the figure OUT_errors.png.
``--lockstep`` runs the approaches in this process on a simulated clock (deterministic, no qi, faster than real
time), and the walker faults (``member_steps_in``: a member walks 0.5 m toward the robot's path while out of its
camera's view; ``stranger_steps_in``: a person never seen steps into its path) too; the other faults and the soak
always run over qi.

The runs' logs go to the folder OUT/ (OUT without its suffix). Its ``.bench_deploy`` marker lists each entry the
tool wrote there, recorded before writing it; a rerun removes exactly those and nothing else. A folder without the
marker, or an entry about to be written that the marker does not list, is refused before anything is written.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

from ssbl_pb.agents.trained import policy_groups
from ssbl_pb.analysis.evaluation import check_policy_spec
from ssbl_pb.bench import deploy as bench
from ssbl_pb.bench import deploy_faults
from ssbl_pb.bench.deploy_faults import FAULTS, WALKER_FAULTS
from ssbl_pb.cli import ArgumentParser, float_in, int_at_least, progress_bar, run
from ssbl_pb.core.layouts import GROUP_MODELS
from ssbl_pb.deploy.perceive import DETECTORS
from ssbl_pb.env.rooms.scenarios import ScenarioMix
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, write_json, write_text
from ssbl_pb.params import APPEARANCES

ROOT = Path(__file__).resolve().parents[1]
MARKER = ".bench_deploy"  # in OUT/: the entries this tool wrote there, one name a line after the header
HEADER = "# written by tools/bench_deploy.py, one name a line; a rerun removes these and nothing else\n"


def _recorded(logs: Path) -> list[str]:
    """The names ``logs``'s marker lists (plain names in ``logs``, nothing above or below it)."""
    lines = (logs / MARKER).read_text(errors="replace").splitlines()[1:]
    return [n for n in lines if n and n not in (".", "..", MARKER) and "/" not in n and "\\" not in n]


def _written_before(logs: Path, planned: list[str]) -> list[Path]:
    """What an earlier run of this tool wrote in ``logs`` (to remove), as its marker lists it; refuses a folder it
    did not write, or one where an entry in ``planned`` exists that the marker does not list."""
    if not logs.is_dir() or not any(logs.iterdir()):
        return []
    if not (logs / MARKER).is_file():
        raise UserError(f"--out: {logs}/ holds files this tool did not write (no {MARKER} marker); choose another "
                        f"--out or move them away")
    recorded = set(_recorded(logs))
    foreign = [n for n in planned if n not in recorded and os.path.lexists(logs / n)]
    if foreign:
        raise UserError(f"--out: {logs}/{foreign[0]} exists and this tool did not write it (not listed in {MARKER}); "
                        f"choose another --out or move it away")
    return [logs / n for n in sorted(recorded) if os.path.lexists(logs / n)]


def _record(logs: Path, name: str) -> Path:
    """``logs / name``, listed in the marker before anything is written there (a killed run is still removed)."""
    with open(logs / MARKER, "a") as fh:
        fh.write(name + "\n")
    return logs / name


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int_at_least(0), default=20, help="seeded approaches (default 20)")
    ap.add_argument("--seed", type=int_at_least(0), default=500_000, help="first held-out seed (>= 0)")
    ap.add_argument("--scenario", default="default", help="the virtual Pepper's scenario (default: the paper's)")
    ap.add_argument("--policy", default="vector", help="the policy deploy runs (default: the shipped vector)")
    ap.add_argument("--groups", choices=GROUP_MODELS, help="the group model of the virtual Pepper and deploy "
                    "(default: the policy's, its config's env.groups)")
    ap.add_argument("--faults", default=",".join(FAULTS), help=f"comma list of {', '.join(FAULTS)}, or none")
    ap.add_argument("--walker-runs", type=int_at_least(1), default=1, metavar="N",
                    help="run each walker fault N times, on its seed and the N-1 after it (default 1)")
    ap.add_argument("--soak", type=float_in(0.0, 86400.0), default=600.0, help="soak seconds (0: none)")
    ap.add_argument("--detector", choices=("auto", *DETECTORS), default="auto",
                    help="deploy's --detector (default auto: the one the virtual Pepper names for its people's look: "
                    "movenet for bodies, colour for box proxies)")
    ap.add_argument("--appearance", choices=APPEARANCES, default="proxy", help="how the virtual Pepper's people "
                    "look, over qi and in lockstep: proxy (boxes, the colour detector's chain; default) or body "
                    "(made from a body model, for MoveNet)")
    ap.add_argument("--no-map", action="store_true", help="run deploy without the room's map (default: with it, "
                    "--map and --start-pose as a user who mapped the room; without it the policy cannot see walls)")
    ap.add_argument("--lockstep", action="store_true", help="approaches in this process on a simulated clock "
                    "(deterministic, no qi)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_deploy",
                    help="results stem: OUT.json, OUT.md, OUT_errors.png and the runs' logs in OUT/")
    args = ap.parse_args(argv)
    faults = [] if args.faults == "none" else args.faults.split(",")
    bad = sorted(set(faults) - set(FAULTS))
    if bad:
        raise UserError(f"--faults {','.join(bad)}: expected a comma list of {', '.join(FAULTS)}, or none")

    ScenarioMix(args.scenario)  # a bad name fails here, before any folder exists
    check_policy_spec(args.policy)
    if args.groups is None:
        args.groups = policy_groups(args.policy)
    check_output_path(args.out.with_suffix(".json"), is_dir=False)
    check_output_path(args.out.with_suffix(".md"), is_dir=False)
    figure = args.out.with_name(args.out.with_suffix("").name + "_errors.png")
    check_output_path(figure, is_dir=False)
    logs = args.out.with_suffix("")
    check_output_path(logs)
    repeats = {f: args.walker_runs if f in WALKER_FAULTS else 1 for f in faults}
    fault_runs = [(f, k, f"fault_{f}" + (f"_{k:02d}" if k else "")) for f in faults for k in range(repeats[f])]
    planned = [f"run{i:02d}" for i in range(args.runs)] + [name for *_, name in fault_runs] + ["soak"] * (args.soak > 0)
    written = _written_before(logs, planned)

    for old in written:  # what an earlier benchmark wrote into the same folder, and only that
        shutil.rmtree(old) if old.is_dir() and not old.is_symlink() else old.unlink()
    logs.mkdir(parents=True, exist_ok=True)
    (logs / MARKER).write_text(HEADER)
    res = {"environment": bench.environment(), "scenario": args.scenario, "policy": args.policy, "groups": args.groups,
           "lockstep": args.lockstep, "detector": args.detector, "appearance": args.appearance,
           "map": not args.no_map, "approaches": [], "faults": []}
    approach = bench.lockstep_approach if args.lockstep else bench.run_approach
    with progress_bar(args.runs, "approaches", "run") as bar:
        for i in range(args.runs):
            folder = _record(logs, f"run{i:02d}")
            res["approaches"].append(approach(folder, args.seed + i, args.policy, args.scenario, groups=args.groups,
                                              detector=args.detector, room_map=not args.no_map,
                                              appearance=args.appearance))
            bar(1)
    if args.runs:
        per_run, pooled = bench.perception_report([logs / f"run{i:02d}" for i in range(args.runs)], args.policy, figure)
        for r, p in zip(res["approaches"], per_run, strict=True):
            r["perception"] = p
        if pooled is not None:
            res["perception"], res["perception_figure"] = pooled, str(figure)
    for f, k, name in fault_runs:
        res["faults"].append(_fault(f, _record(logs, name), args.lockstep, k))
    if args.soak > 0:
        res["soak"] = deploy_faults.soak(_record(logs, "soak"), args.soak, args.seed, args.policy)
    write_json(args.out.with_suffix(".json"), res)
    text = bench.markdown(res)
    write_text(args.out.with_suffix(".md"), text)
    print(text)
    return 0


def _fault(fault: str, folder: Path, lockstep: bool, walker_run: int, tries: int = 2) -> dict[str, Any]:
    """``run_fault``, tried again (in a fresh folder) when deploy ended before the base moved and the fault could
    not be injected; after ``tries`` such ends, a row saying so, so that one late frame loses no other result."""
    for _ in range(tries):
        try:
            return deploy_faults.run_fault(fault, folder, lockstep=lockstep, walker_run=walker_run)
        except deploy_faults.NotInjected as exc:
            print(f"warning: {exc}", flush=True)
            note = str(exc)
            shutil.rmtree(folder, ignore_errors=True)
    return {"fault": fault, "exit_code": None, "not_injected": note}


if __name__ == "__main__":
    run(main)
