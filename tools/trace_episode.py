#!/usr/bin/env python
"""Trace one episode step by step: DIR/trace.csv (a row per step), DIR/trace.png (from above and over time) and
DIR/summary.json (how it ended, lateral reversals, nearest-member side swaps).

What the policy asked and what its shield let through, where the true and the perceived places lie, how many members
perception holds: for reading why an episode of an evaluation failed (its seed is in episodes.csv's `seed` column).

Examples:
    python tools/trace_episode.py --policy vector --scenario mixed --perception movenet --seed 500157 \
        --out results/trace_500157
    python tools/trace_episode.py --policy vector --scenario mixed --perception movenet --seed 500157 \
        --oracle members --out results/trace_500157_true_members    # the member blocks from the true state
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.evaluation import Setup, check_policy_spec
from ssbl_pb.analysis.trace import write_trace
from ssbl_pb.cli import ArgumentParser, int_at_least, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, output_dir
from ssbl_pb.perception.groups.observation_model import ORACLE_PARTS


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policy", required=True,
                    help="sffm | random | straight | vector (the shipped model) | PATH (.zip or run directory)")
    ap.add_argument("--seed", type=int_at_least(0), default=1000, help="the episode's seed (as evaluate.py's)")
    ap.add_argument("--scenario", default="default", help="as evaluate.py's --scenario")
    ap.add_argument("--perception", choices=["off", "movenet", "colour"], default="off",
                    help="the true state (off, default) or the observation model of a detector's chain")
    ap.add_argument("--oracle", default="",
                    help=f"comma-separated parts of the observation taken from the true state, with --perception "
                         f"(diagnostics: {', '.join(ORACLE_PARTS)})")
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    args = ap.parse_args(argv)

    check_policy_spec(args.policy)
    check_output_path(args.out)
    oracle = [p for p in args.oracle.split(",") if p]
    bad = [p for p in oracle if p not in ORACLE_PARTS]
    if bad:
        raise UserError(f"--oracle {args.oracle!r}: {bad[0]!r} is not one of {list(ORACLE_PARTS)}")
    if oracle and args.perception == "off":
        raise UserError("--oracle needs --perception movenet or colour (with it off the policy sees the true state)")
    env_kwargs: tuple = ()
    if args.perception != "off":
        env_kwargs = (("perception", {"preset": args.perception, "oracle": oracle} if oracle else args.perception),)
    setup = Setup(args.policy, "vector", args.scenario, env_kwargs)
    with output_dir(args.out) as out:  # a bad scenario or model fails inside: the folders it made are removed
        summary = write_trace(out, setup, args.seed)
    print(f"seed {args.seed}: {summary['outcome']} after {summary['episode_time_s']:.1f} s"
          + (f" ({summary['failure']})" if summary.get("failure", "none") != "none" else "")
          + f"; shield {summary['shield_intervention_rate']:.0%} of steps, lateral reversals "
            f"{summary['lateral_reversals']}, nearest member side swaps {summary['nearest_member_side_swaps']} "
            f"-> {args.out}/trace.png")
    return 0


if __name__ == "__main__":
    run(main)
