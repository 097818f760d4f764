#!/usr/bin/env python
"""Render one episode from above, zones drawn (intimate red, personal orange, o-space green, slot X).

Examples:
    python tools/render_episode.py --policy sffm --seed 3 --out results/videos/sffm_3.mp4
    python tools/render_episode.py --policy vector --seed 3 --out results/videos/vector_3.mp4 --first-person

The people are box proxies, or with --first-person bodies made from a body model (--appearance sets either).
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.evaluation import build_policy, check_policy_spec, outcome
from ssbl_pb.analysis.video import contact_sheet, record_episode, save_png, write_mp4
from ssbl_pb.cli import ArgumentParser, fail, int_at_least, int_in, run
from ssbl_pb.env.gymenv.approach import make_env
from ssbl_pb.files import check_output_path, output_dir
from ssbl_pb.params import APPEARANCES


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--policy", required=True, help="sffm | random | straight | vector | PATH (.zip or run dir)")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="episode seed (the same seed gives the same start)")
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--out", type=Path, required=True, help="output .mp4")
    ap.add_argument("--width", type=int_in(64, 4096), default=480, help="video width in pixels (64-4096)")
    ap.add_argument("--first-person", action="store_true", help="also write OUT.first_person.png (contact sheet)")
    ap.add_argument("--appearance", choices=APPEARANCES, help="how the people look: proxy (boxes) or body "
                    "(default: body with --first-person, else proxy)")
    args = ap.parse_args(argv)
    look = args.appearance or ("body" if args.first_person else "proxy")

    if args.out.suffix != ".mp4":
        return fail(f"--out {args.out}: expected a .mp4 file name")
    check_policy_spec(args.policy)
    check_output_path(args.out, is_dir=False)
    env = make_env(scenario=args.scenario, render_mode="rgb_array", render_width=args.width,
                   world={"humans": {"appearance": look}})
    env.unwrapped.world.set_body_seed(args.seed)  # the members' bodies follow the episode's seed
    policy = build_policy(args.policy, env)
    top, fp, m = record_episode(env, policy, args.seed, first_person=5 if args.first_person else 0)
    with output_dir(args.out.parent):
        write_mp4(args.out, top)
        if fp:
            save_png(args.out.with_suffix(".first_person.png"), contact_sheet(fp[:24]))
    print(f"{outcome(m)} after {m['episode_time_s']:.1f} s, {len(top)} frames -> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
