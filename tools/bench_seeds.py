#!/usr/bin/env python
"""Seeds of one training recipe side by side: each seed's final model evaluated per scenario and observation model on
the same held-out starts, and each measure's mean and spread over the seeds (success, the four social measures
the comparison with the SFFM judges, intrusions), as rl-baselines3-zoo reports its benchmark.

Writes OUT.json (per seed and summarised), OUT.md (a table per observation model) and OUT.png (success per scenario,
a dot per seed; the social measures per seed).
    python tools/bench_seeds.py --runs runs/vector_recipe_s1,runs/vector_recipe_s2,runs/vector_recipe_s3
    python tools/bench_seeds.py --runs runs/vector_recipe_s1,runs/vector_recipe_s2 --scenarios default,mixed \\
        --perception off,movenet --episodes 50 --out results/seeds_quick
"""

from __future__ import annotations

import json
from pathlib import Path

from ssbl_pb.analysis.report import write_json
from ssbl_pb.bench.policies import (
    add_bench_args,
    bench_table,
    check_perceptions,
    plot_spread,
    seed_spread,
    spread_markdown,
)
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, output_dir, write_text

ROOT = Path(__file__).resolve().parents[1]


def final_model(run_dir: Path) -> str:
    """A recipe run's final model (its ``recipe.json``), or the directory itself when it holds a model."""
    rec = run_dir / "recipe.json"
    if rec.is_file():
        try:
            final = json.loads(rec.read_text())["final_model"]
        except (json.JSONDecodeError, KeyError) as e:
            raise UserError(f"{rec}: expected the recipe's JSON with 'final_model' ({e})") from e
        path = Path(final) if Path(final).is_absolute() else ROOT / final
        if not (path / "model.zip").is_file():
            path = run_dir / Path(final).name  # the run moved: its final stage's folder inside it
        if (path / "model.zip").is_file():
            return str(path)
        raise UserError(f"{rec}: its final model {final} has no model.zip (the recipe has not finished: run it "
                        f"again to continue)")
    if (run_dir / "model.zip").is_file():
        return str(run_dir)
    raise UserError(f"--runs {run_dir}: expected a recipe's output (recipe.json) or a model's folder (model.zip)")


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--runs", required=True, help="comma list of a recipe's outputs, one per seed "
                    "(tools/train_pb.py --recipe ... --out DIR --seed N), or model folders")
    add_bench_args(ap, "default,mixed,real,default@furnished,mixed@furnished", "off,movenet")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "recipe_seeds",
                    help="results stem: OUT.json, OUT.md, OUT.png (default results/recipe_seeds)")
    args = ap.parse_args(argv)

    runs = [Path(r) for r in args.runs.split(",") if r]
    scs, percs = args.scenarios.split(","), args.perception.split(",")
    check_perceptions(percs)
    check_output_path(args.out.with_suffix(".json"), is_dir=False)
    models = {str(r): final_model(r) for r in runs}
    if len(set(models.values())) < len(models):
        raise UserError(f"--runs {args.runs}: a model is named twice")
    by_model = {m: r for r, m in models.items()}
    table = bench_table(list(models.values()), scs, percs, args.episodes, args.seed,
                        row_name=lambda pol, perc: f"{by_model[pol]} ({perc})")
    spread = seed_spread(table, list(models), percs, scs)
    text = (f"{len(runs)} seeds ({', '.join(models)}), {args.episodes} held-out starts per scenario (seeds "
            f"{args.seed}-{args.seed + args.episodes - 1}); mean ± std over the seeds.\n\n"
            + spread_markdown(spread, scs))
    with output_dir(args.out.parent):
        write_json(args.out.with_suffix(".json"), {"runs": models, "episodes": args.episodes, "seed": args.seed,
                                                   "per_seed": table, "spread": spread})
        write_text(args.out.with_suffix(".md"), text)
        plot_spread(spread, scs, list(models), args.out.with_suffix(".png"))
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
