"""Calibrate a camera from chessboard photographs; write a ROS camera_info YAML, a PNG and a Markdown report.

    python tools/calibrate_camera.py ../shared/data/calib/left*.jpg --board 9x6 --square 0.025 \
        --fix-aspect --out results/calib/left.yaml --stability 3

Exit code 2 on bad input (unreadable files, no board found in enough images, wrong --board).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ssbl_pb.calib import reports
from ssbl_pb.calib.intrinsics import calibrate, leave_k_out, parse_board
from ssbl_pb.calib.io import check_outputs
from ssbl_pb.cli import ArgumentParser, UserError, command_line, int_at_least, run


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("images", nargs="+", type=Path, help="chessboard photographs (all the same size)")
    ap.add_argument("--board", default="9x6", help="inner corners COLSxROWS (default 9x6)")
    ap.add_argument("--square", type=float, default=0.025, help="square size in metres (default 0.025)")
    ap.add_argument("--out", type=Path, required=True, help="camera YAML to write (ROS camera_info layout)")
    ap.add_argument("--fix-aspect", action="store_true", help="fix fx = fy (OpenCV's CALIB_FIX_ASPECT_RATIO)")
    ap.add_argument("--fix-k3", action="store_true", help="do not fit the k3 distortion term")
    ap.add_argument("--zero-tangent", action="store_true", help="assume no tangential distortion")
    ap.add_argument("--outlier-factor", type=float, default=3.0,
                    help="reject images whose error exceeds this x the median (0: keep all; default 3)")
    ap.add_argument("--min-images", type=int_at_least(1), default=5, help="fail below this many usable images")
    ap.add_argument("--stability", type=int_at_least(0), default=0, metavar="K",
                    help="also refit with every K-subset left out and report the largest change")
    ap.add_argument("--name", default="pepper_camera_top", help="camera_name in the YAML")
    args = ap.parse_args(argv)
    check_outputs(args.out, (".png", ".md"))
    if args.stability and len(args.images) - args.stability < 3:  # known before any image is read
        raise UserError(f"--stability {args.stability}: leaving {args.stability} out of {len(args.images)} images "
                        f"keeps fewer than 3; give more images or a smaller K")
    board = parse_board(args.board)
    res = calibrate(args.images, board, args.square, fix_aspect=args.fix_aspect, zero_tangent=args.zero_tangent,
                    fix_k3=args.fix_k3, outlier_factor=args.outlier_factor, min_images=args.min_images,
                    progress=len(args.images) > 20, name=args.name)
    for p, why in res.detections.rejected:
        print(f"rejected {p}: {why}", file=sys.stderr)
    stab = leave_k_out(res, board, args.square, args.stability, progress=True) if args.stability else None
    command = command_line("tools/calibrate_camera.py", argv)
    res.camera.to_yaml(args.out, header=f"{command}\nRMS reprojection error {res.rms:.4f} px")
    reports.intrinsics_figure(res, board, args.out.with_suffix(".png"))
    md = reports.intrinsics_markdown(res, command, stab, args.stability)
    reports.write_markdown(args.out.with_suffix(".md"), md)
    c = res.camera
    print(f"{args.out}: RMS {res.rms:.3f} px over {len(res.per_image)} images; fx {c.fx:.2f} fy {c.fy:.2f} "
          f"cx {c.cx:.2f} cy {c.cy:.2f}")
    if stab is not None:
        print(f"leave-{args.stability}-out max change: fx {abs(stab[:, 0]).max():.2%} cx {abs(stab[:, 2]).max():.2%}"
              f" cy {abs(stab[:, 3]).max():.2%} over {len(stab)} subsets")
    return 0


if __name__ == "__main__":
    run(main)
