#!/usr/bin/env python
"""Analyse perceptual-study ratings: paired t-tests per item (t, df, p, Cohen's d_z) and a bar plot (Fig. 8).

RATINGS.csv layout (long format, header required): participant,condition,item,rating[,video]
items: polite, sociable, rude, human_like; ratings: integers 1-7. Example: docs/examples/ratings_example.csv
    python tools/analyze_study.py docs/examples/ratings_example.csv --out results/study
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ssbl_pb.cli import fail, run


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ratings", type=Path, help="ratings CSV")
    ap.add_argument("--conditions", nargs=2, metavar=("A", "B"), help="the two conditions (A - B is tested)")
    ap.add_argument("--out", type=Path, default=Path("results/study"))
    args = ap.parse_args(argv)

    from ssbl_pb.study import StudyError, analyze, markdown, plot

    try:
        res = analyze(args.ratings, tuple(args.conditions) if args.conditions else None)
        args.out.mkdir(parents=True, exist_ok=True)
    except (StudyError, OSError) as exc:
        return fail(exc)
    (args.out / "study.json").write_text(json.dumps(res, indent=2))
    table = markdown(res)
    (args.out / "study.md").write_text(f"# Perceptual study: {res['conditions'][0]} vs {res['conditions'][1]}\n\n"
                                       f"{table}\n")
    plot(res, args.out / "study.png")
    print(table)
    print(f"-> {args.out}/study.md, study.json, study.png")
    return 0


if __name__ == "__main__":
    run(main)
