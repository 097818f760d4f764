#!/usr/bin/env python
"""Analyse perceptual-study ratings: paired t-tests per item (t, df, p, Cohen's d_z) and a bar plot (Fig. 8).

RATINGS.csv layout (long format, header required): participant,condition,item,rating[,video]
items: polite, sociable, rude, human_like; ratings: integers 1-7. Example: docs/examples/ratings_example.csv
    python tools/analyze_study.py docs/examples/ratings_example.csv --out results/study
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.study import analyze, markdown, plot
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.files import check_output_path, output_dir, write_json, write_text


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("ratings", type=Path, help="ratings CSV")
    ap.add_argument("--conditions", nargs=2, metavar=("A", "B"), help="the two conditions (A - B is tested)")
    ap.add_argument("--out", type=Path, default=Path("results/study"))
    args = ap.parse_args(argv)

    check_output_path(args.out)
    res = analyze(args.ratings, tuple(args.conditions) if args.conditions else None)
    table = markdown(res)
    with output_dir(args.out):
        write_json(args.out / "study.json", res)
        write_text(args.out / "study.md", f"# Perceptual study: {res['conditions'][0]} vs {res['conditions'][1]}"
                                          f"\n\n{table}\n")
        plot(res, args.out / "study.png")
    print(table)
    print(f"-> {args.out}/study.md, study.json, study.png")
    return 0


if __name__ == "__main__":
    run(main)
