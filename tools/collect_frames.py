#!/usr/bin/env python
"""Collect Pepper's first-person frames for training the camera autoencoders (tools/train_ae.py).

Each episode is driven by one policy of a mix (default random, sffm, straight, vector, in turn) so the frames
cover the task from far away to standing in the group. Every frame comes with the robot's speed and, for
evaluation only, each member's position relative to the robot and its pixel when visible (layout:
ssbl_pb/analysis/frames.py).

Examples:
    python tools/collect_frames.py --episodes 120 --out results/frames/frames.npz
    python tools/collect_frames.py --episodes 40 --size 96 --policies random,sffm --out frames96.npz
    python tools/collect_frames.py --episodes 120 --camera-hfov 26.5 --out results/frames26/frames.npz
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.evaluation import check_policy_spec
from ssbl_pb.analysis.frames import check_hfov, collect, save_frames
from ssbl_pb.cli import ArgumentParser, int_at_least, progress_bar, run
from ssbl_pb.env.rooms.scenarios import ScenarioMix
from ssbl_pb.errors import UserError
from ssbl_pb.files import check_output_path


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--episodes", type=int, required=True, help="number of episodes")
    ap.add_argument("--out", type=Path, required=True, help="output .npz")
    ap.add_argument("--size", type=int, default=64, help="frame side in pixels (the encoder's input; default 64)")
    ap.add_argument("--policies", default="random,sffm,straight,vector",
                    help="comma-separated policies driving the episodes in turn (baselines or a trained model)")
    ap.add_argument("--scenario", default="mixed", help="default | mixed | behind | FORMATION[-N] | a,b,...")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="seed of the first episode; episode i uses seed+i")
    ap.add_argument("--camera-hfov", type=float, default=None, metavar="DEG",
                    help="the camera's field of view, degrees (default Pepper's top camera, 56.3; the paper's "
                         "Unity camera: 26.5). The encoder trained on these frames keeps it")
    args = ap.parse_args(argv)

    if args.out.suffix != ".npz":
        raise UserError(f"--out {args.out}: expected a .npz file name")
    if not 16 <= args.size <= 256:
        raise UserError(f"--size {args.size}: expected 16..256 pixels")
    if args.episodes < 1:
        raise UserError(f"--episodes {args.episodes}: expected an integer >= 1")
    policies = tuple(p for p in args.policies.split(",") if p)
    if not policies:
        raise UserError(f"--policies {args.policies!r}: expected at least one policy")
    for p in policies:
        check_policy_spec(p)
    check_hfov(args.camera_hfov)
    check_output_path(args.out, "--out", is_dir=False)
    ScenarioMix(args.scenario)  # a bad scenario fails before any episode
    with progress_bar(args.episodes, "collect frames") as bar:
        data = collect(args.episodes, args.size, args.seed, policies, args.scenario, bar, args.camera_hfov)
    save_frames(args.out, data)
    print(f"{len(data['frames'])} frames of {args.size}x{args.size} ({float(data['camera_hfov']):.1f} deg) from "
          f"{args.episodes} episodes -> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
