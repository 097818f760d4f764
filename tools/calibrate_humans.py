"""Human-motion statistics from ETH/UCY against the SFFM; write fitted SocialParams fields, a PNG and a report.

    python tools/calibrate_humans.py --data ../shared/data/trajectories/eth_ucy_raw \
        --out results/calib/humans.yaml                                    # + humans.png, humans.md

Exit code 2 on bad input (missing folders or files, malformed obsmat).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ssbl_pb.calib import reports
from ssbl_pb.calib.humans import SCENES, fit_social, real_stats, sim_stats
from ssbl_pb.calib.io import check_outputs
from ssbl_pb.cli import ArgumentParser, UserError, command_line, int_at_least, run
from ssbl_pb.files import write_yaml
from ssbl_pb.params import SocialParams, from_dict

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "trajectories" / "eth_ucy_raw"


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder holding the ETH/UCY scene folders")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), help="scene folders to use")
    ap.add_argument("--out", type=Path, required=True, help="YAML of SocialParams fields (+ .png, .md)")
    ap.add_argument("--episodes", type=int_at_least(1), default=40, help="simulated group episodes per parameter set")
    ap.add_argument("--seed", type=int_at_least(0), default=0)
    args = ap.parse_args(argv)
    check_outputs(args.out, (".png", ".md"))
    if not args.data.is_dir():
        raise UserError(f"{args.data}: data folder not found (give --data)")
    real = real_stats(args.data, tuple(args.scenes))
    fields, notes = fit_social(real["all"])
    fitted = from_dict(SocialParams, fields, f"fitted from {args.data}")
    sims = {"default": sim_stats(SocialParams(), args.episodes, seed=args.seed, progress=True),
            "fitted": sim_stats(dataclasses.replace(fitted), args.episodes, seed=args.seed, progress=True)}
    command = command_line("tools/calibrate_humans.py", argv)
    write_yaml(args.out, fields, header=f"{command}\nSocialParams fields fitted to ETH/UCY ({', '.join(args.scenes)})")
    reports.humans_figure(real["all"], sims, args.out.with_suffix(".png"))
    reports.write_markdown(args.out.with_suffix(".md"), reports.humans_markdown(real, sims, fields, notes, command))
    print(f"{args.out}: " + ", ".join(f"{k} {v}" for k, v in fields.items()))
    return 0


if __name__ == "__main__":
    run(main)
