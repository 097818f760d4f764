"""Camera height, pitch and roll from one image of a chessboard lying on the floor; updates the camera YAML.

    python tools/camera_pose.py floor.png --camera cam.yaml --board 9x6 --square 0.1 \
        --board-centre 2.0 0.0 --out cam_posed.yaml

The board centre position (robot frame: x forward, y left, metres) is optional and only checked.
Exit code 2 on bad input.
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.calib.extrinsics import pose_from_image
from ssbl_pb.calib.intrinsics import parse_board, read_grey
from ssbl_pb.calib.io import check_outputs
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.perception.camera import PinholeCamera


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("image", type=Path, help="image of the board lying flat on the floor")
    ap.add_argument("--camera", type=Path, required=True, help="calibrated camera YAML (intrinsics)")
    ap.add_argument("--board", default="9x6", help="inner corners COLSxROWS")
    ap.add_argument("--square", type=float, required=True, help="square size in metres")
    ap.add_argument("--board-centre", type=float, nargs=2, metavar=("X", "Y"),
                    help="where the board centre lies, robot frame (m); reported against the fit")
    ap.add_argument("--forward", type=float, help="camera_forward to record (m ahead of the base centre)")
    ap.add_argument("--out", type=Path, help="YAML to write (default: overwrite --camera)")
    args = ap.parse_args(argv)
    check_outputs(args.out or args.camera, (), "--out" if args.out else "--camera (rewritten without --out)")
    cam = PinholeCamera.from_yaml(args.camera)  # its errors name the file
    if args.forward is not None:
        cam.forward = args.forward
    r = pose_from_image(cam, read_grey(args.image), parse_board(args.board), args.square, where=str(args.image))
    out = args.out or args.camera
    r.camera.to_yaml(out, header=f"pose from {args.image}: reprojection RMS {r.rms_px:.3f} px")
    print(f"{out}: height {r.height:.4f} m, pitch {r.pitch_deg:.3f} deg, roll {r.roll_deg:.3f} deg "
          f"(board RMS {r.rms_px:.3f} px)")
    seen = r.board_centre_seen
    msg = f"board centre seen at x {seen[0]:.3f} y {seen[1]:.3f} m"
    if args.board_centre:
        dx, dy = seen[0] - args.board_centre[0], seen[1] - args.board_centre[1]
        msg += f"; given {args.board_centre}: off by {dx:+.3f}, {dy:+.3f} m"
    print(msg)
    return 0


if __name__ == "__main__":
    run(main)
