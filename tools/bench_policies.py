#!/usr/bin/env python
"""Success rates (and main social metrics) of policies per scenario over held-out seeded episodes.

Writes results/bench_policies.json and a Markdown table (results/bench_policies.md) for docs/benchmarks.md.
    python tools/bench_policies.py --policies sffm,straight,random --episodes 200
    python tools/bench_policies.py --policies vector --scenarios default,mixed --episodes 200
    python tools/bench_policies.py --policies vector --scenarios mixed,default@map:results/rooms/lab.yaml \
        --perception off,on      # a map room (SCENARIO:ROOM_YAML); the observation model off and on
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ssbl_pb.analysis.report import write_json
from ssbl_pb.bench.policies import add_bench_args, bench_table, check_perceptions
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.files import check_output_path, output_dir, write_text

ROOT = Path(__file__).resolve().parents[1]

SCENARIOS = "default,vis_a_vis,l_shape,side_by_side,circular,behind,mixed"


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policies", default="sffm,straight,random")
    add_bench_args(ap, SCENARIOS, "off")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_policies",
                    help="results stem: OUT.json and OUT.md (default results/bench_policies)")
    args = ap.parse_args(argv)

    pols, scs, percs = args.policies.split(","), args.scenarios.split(","), args.perception.split(",")
    check_perceptions(percs)
    check_output_path(args.out.with_suffix(".json"), is_dir=False)
    table = bench_table(pols, scs, percs, args.episodes, args.seed)
    with output_dir(args.out.parent):
        write_results(args, table, scs, write_json, write_text)
    return 0


def write_results(args: Any, table: dict[str, dict[str, dict]], scs: list[str], write_json: Any,
                  write_text: Any) -> None:
    write_json(args.out.with_suffix(".json"), {"episodes": args.episodes, "seed": args.seed, "results": table})
    lines = ["| policy | " + " | ".join(scs) + " |", "|---|" + "---|" * len(scs)]
    for pol, row in table.items():
        lines.append(f"| {pol} | " + " | ".join(f"{row[sc]['success_rate']:.1%} ({row[sc]['violation_rate']:.1%} v)"
                                                 for sc in scs) + " |")
    text = (f"Success rate (and share of episodes ended by a collision or intimate-zone intrusion, 'v') over "
            f"{args.episodes} episodes per scenario, seeds {args.seed}-{args.seed + args.episodes - 1}.\n\n"
            + "\n".join(lines) + "\n")
    write_text(args.out.with_suffix(".md"), text)
    print(text)


if __name__ == "__main__":
    run(main)
