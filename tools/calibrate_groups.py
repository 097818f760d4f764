#!/usr/bin/env python
"""Real conversational groups (F-formation .mat files) against the simulator's: a groups YAML, a figure, a table.

Reads the annotated frames of each dataset (folders holding features.mat and groundtruth.mat, found at or below
each DATA path; layout in shared/data/fformations/SOURCES.md) and writes, per group size, the distributions of
member-to-centroid distance, nearest-neighbour spacing, spacing irregularity and orientation offset, with every
real layout (OUT, for `make_env(groups_yaml=...)` and `--groups-yaml`), histograms of real vs simulated groups
(OUT with .png) and a table of medians (OUT with .md).

Examples:
    python tools/calibrate_groups.py --out results/calib/groups.yaml
    python tools/calibrate_groups.py ../shared/data/fformations/CocktailParty --out cocktail.yaml
    python tools/evaluate.py --policy sffm --groups-yaml results/calib/groups.yaml --out results/eval_groups

The groups YAML shipped with the package (ssbl_pb/data/groups.yaml) is this tool's output on all of
shared/data/fformations. Exit code 2 on bad input (a missing or malformed .mat file, an empty annotated frame,
a member id with no position in the file), with nothing written.
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.calib import groups
from ssbl_pb.calib.fformations import load_datasets
from ssbl_pb.calib.io import check_outputs, save_figure
from ssbl_pb.cli import ArgumentParser, UserError, command_line, int_at_least, run
from ssbl_pb.core.layouts import GroupModel, parse_group_data
from ssbl_pb.files import write_text, write_yaml
from ssbl_pb.params import SocialParams

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "fformations"


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("data", nargs="*", type=Path, default=[DEFAULT_DATA],
                    help=f"dataset folders or folders above them (default {DEFAULT_DATA})")
    ap.add_argument("--out", type=Path, required=True, help="groups YAML to write (+ .png figure, .md table)")
    ap.add_argument("--per-size", type=int, default=2000, help="simulated groups per size (default 2000)")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="seed of the simulated groups")
    args = ap.parse_args(argv)
    if args.per_size < 1:
        raise UserError(f"--per-size {args.per_size}: expected an integer >= 1")
    if args.out.suffix not in (".yaml", ".yml"):
        raise UserError(f"--out {args.out}: expected a .yaml file name (the figure and table go beside it)")
    check_outputs(args.out, (".png", ".md"))
    datasets = load_datasets(args.data)
    content = groups.groups_yaml(datasets)
    data = parse_group_data(content, str(args.out))
    social = SocialParams()
    real = groups.real_stats(datasets)
    sizes = [n for n in groups.SIM_SIZES if n in data.sizes]
    sims = {name: groups.sim_stats(GroupModel(name, loaded=data), social, args.per_size, args.seed, sizes)
            for name in ("calibrated", "paper")}
    rows = groups.compare_table(real, sims)
    command = command_line("tools/calibrate_groups.py", argv)
    header = (f"{command}\nReal conversational groups (F-formations), per size: quantiles (percent levels in "
              f"'quantiles') of member-to-centroid distance (m, per group mean), nearest-neighbour spacing (m, per "
              f"member), spacing irregularity (CV of member-to-centroid distances) and orientation offset (deg), "
              f"and every layout re-centred on its centroid (x1, y1, x2, y2, ... in m).")
    write_yaml(args.out, content, header=header)
    save_figure(args.out.with_suffix(".png"), groups.figure(real, sims))
    write_text(args.out.with_suffix(".md"), groups.markdown(rows, datasets, command, sims))
    for r in rows:
        print(f"groups of {r['size']}: member-to-centroid real {r['real_centroid_distance_m']:.2f} m, calibrated "
              f"{r['calibrated_centroid_distance_m']:.2f} ({100 * r['calibrated_centroid_distance_m_error']:+.0f} %), "
              f"nearest neighbour real {r['real_nearest_neighbour_m']:.2f} m, calibrated "
              f"{r['calibrated_nearest_neighbour_m']:.2f} ({100 * r['calibrated_nearest_neighbour_m_error']:+.0f} %)")
    print(f"-> {args.out} (+ .png, .md)")
    return 0


if __name__ == "__main__":
    run(main)
