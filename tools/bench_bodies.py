#!/usr/bin/env python
"""How often MoveNet (deploy's detector for real people) finds the simulator's person bodies in the virtual
Pepper's camera frames (``ssbl_pb/bench/body_detection.py``): each shipped body alone at 1-5 m seen from the
front, the side and the back, and the members of the env's groups (also drawn as box proxies, for comparison),
at 320x240 and 640x480; and the facing and range deploy's MoveNet chain gives each body alone (against its true
yaw and distance). Writes OUT.json (every sample) and OUT.md (the tables) and prints the Markdown.

    python tools/bench_bodies.py                            # 10 bodies x 7 distances x 3 views, 20 groups (~4 min)
    python tools/bench_bodies.py --groups 0 --out /tmp/bodies
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from ssbl_pb.cli import ArgumentParser, int_at_least, run
from ssbl_pb.files import check_output_path, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--groups", type=int_at_least(0), default=20, help="group scenes (default 20; 0: none)")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="seed of the group scenes (default 0)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_bodies",
                    help="results stem: OUT.json and OUT.md (default results/bench_bodies)")
    args = ap.parse_args(argv)
    for suffix in (".json", ".md"):
        check_output_path(args.out.with_suffix(suffix), is_dir=False)
    from ssbl_pb.bench import body_detection as bd  # lazy: the renderer and MoveNet (~1.7 s), not for --help
    from ssbl_pb.bench import body_pose  # lazy: as above

    detect = bd.movenet_detector()  # raises naming the install command when MoveNet is missing
    single = bd.single(detect)
    group = [row for look in ("body", "proxy") for row in bd.group(detect, args.groups, args.seed, appearance=look)
             ] if args.groups else []  # the box proxies in the same scenes, for comparison
    command = "python tools/bench_bodies.py " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None
                                                                                 else argv))
    pose = body_pose.placed()
    text = bd.markdown(single, group) + "\n" + body_pose.markdown(pose) + f"\n`{command.strip()}`\n"
    write_json(args.out.with_suffix(".json"), {"command": command.strip(), "thresholds": list(bd.THRESHOLDS),
                                               "match_iou": bd.MATCH_IOU, "single": single, "group": group,
                                               "pose": pose})
    write_text(args.out.with_suffix(".md"), text)
    print(text)
    return 0


if __name__ == "__main__":
    run(main)
