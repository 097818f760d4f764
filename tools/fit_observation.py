#!/usr/bin/env python
"""The observation model's numbers measured from deploy runs against the virtual Pepper
(``ssbl_pb/bench/observation_fit.py``): range and bearing noise, misses, how much of a person must be in the image
and may hide behind others, facing noise; beside the model's values now. Reads the run folders
``tools/bench_deploy.py --out DIR`` writes (``DIR/runNN``; give DIR or single run folders). Writes OUT.json,
OUT.md and OUT.png (range noise against distance, detected share against the share in the image and hidden) and
prints the Markdown.

    python tools/bench_deploy.py --scenario mixed --runs 10 --lockstep --appearance body --detector movenet \\
        --faults none --soak 0 --out results/bench_deploy_movenet
    python tools/fit_observation.py results/bench_deploy_movenet --out results/observation_fit_movenet
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, progress_bar, run
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]


def run_folders(paths: list[Path]) -> list[Path]:
    """The run folders (holding ``deploy/`` and ``virtual_pepper.jsonl``) in ``paths``, each a run folder or a
    benchmark's output folder of them."""
    out = []
    for p in paths:
        if (p / "virtual_pepper.jsonl").is_file():
            out.append(p)
            continue
        runs = sorted(q for q in p.glob("run*") if (q / "virtual_pepper.jsonl").is_file()) if p.is_dir() else []
        if not runs:
            raise UserError(f"{p}: expected a run folder (with virtual_pepper.jsonl and deploy/) or a folder of them "
                            "(tools/bench_deploy.py --out)")
        out.extend(runs)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("runs", type=Path, nargs="+", help="bench_deploy output folders or single run folders")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "observation_fit",
                    help="results stem: OUT.json, OUT.md and OUT.png (default results/observation_fit)")
    ap.add_argument("--detector", choices=["movenet", "colour"], default="movenet",
                    help="the chain the runs used (bench_deploy's --detector; default movenet): the model it is "
                         "measured for")
    args = ap.parse_args(argv)
    folders = run_folders(args.runs)
    for suffix in (".json", ".md", ".png"):
        check_output_path(args.out.with_suffix(suffix), is_dir=False)
    from ssbl_pb.bench.observation_fit import fit, markdown, plot  # lazy: scipy and the camera model, not for --help
    from ssbl_pb.bench.perception_errors import ErrorParams, analyse_folder, pool
    from ssbl_pb.perception.groups.observation_model import PerceptionParams

    base = PerceptionParams.preset(args.detector)
    errors = ErrorParams() if base.keypoints else ErrorParams(edge_margin_m=0.0)  # what perceive asks of a box
    parts = []
    with progress_bar(len(folders), "runs", "run") as bar:
        for folder in folders:
            parts.append(analyse_folder(folder, p=errors))
            bar(1)
    result = fit(pool(parts), base)
    current = dataclasses.asdict(base)
    command = "python tools/fit_observation.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None
                                                                                      else argv))
    text = f"Command: `{command}` ({len(folders)} runs)\n\n" + markdown(result, current)
    write_json(args.out.with_suffix(".json"), {**result, "runs": [str(f) for f in folders], "command": command})
    write_text(args.out.with_suffix(".md"), text)
    plot(result, args.out.with_suffix(".png"), f"{len(folders)} runs, {args.detector}")
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
