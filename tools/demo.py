#!/usr/bin/env python
"""Demo of the simulated world: a robot moving into a two-person F-formation, the members opening it.

Writes OUT/demo_topdown.mp4 (top-down, zones drawn) and OUT/demo_first_person.png (Pepper's camera frames). The
people are bodies made from a body model (--appearance proxy: the training's box proxies).
    python tools/demo.py --out results/demo
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.evaluation import build_policy, check_policy_spec
from ssbl_pb.analysis.video import contact_sheet, record_episode, save_png, write_mp4
from ssbl_pb.cli import ArgumentParser, int_at_least, int_in, run
from ssbl_pb.env.gymenv.approach import make_env
from ssbl_pb.files import check_output_path, output_dir
from ssbl_pb.params import APPEARANCES


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("results/demo"), help="output directory")
    ap.add_argument("--policy", default="sffm", help="who drives the robot (default: the SFFM baseline)")
    ap.add_argument("--seed", type=int_at_least(0), default=1000)
    ap.add_argument("--width", type=int_in(64, 4096), default=480, help="video width in pixels (64-4096)")
    ap.add_argument("--appearance", choices=APPEARANCES, default="body",
                    help="how the people look: body (default) or proxy (boxes)")
    args = ap.parse_args(argv)

    check_policy_spec(args.policy)
    check_output_path(args.out)
    env = make_env(render_mode="rgb_array", render_width=args.width, world={"humans": {"appearance": args.appearance}})
    env.unwrapped.world.set_body_seed(args.seed)  # the members' bodies follow the episode's seed
    policy = build_policy(args.policy, env)
    top, fp, m = record_episode(env, policy, args.seed, first_person=4, fp_size=96)
    with output_dir(args.out):
        write_mp4(args.out / "demo_topdown.mp4", top)
        labels = [f"t={4 * i * 0.1:.1f}s" for i in range(len(fp))]
        save_png(args.out / "demo_first_person.png", contact_sheet(fp[:30], labels=labels[:30]))
    print(f"{args.policy}: {'joined the group' if m['success'] else 'did not join'} in {m['episode_time_s']:.1f} s; "
          f"members moved {m['human_displacement_m']:.2f} m -> {args.out}/demo_topdown.mp4, demo_first_person.png")
    return 0


if __name__ == "__main__":
    run(main)
