"""Camera height, tilt and room extents from a depth scan (PLY/PCD): RANSAC floor and wall planes (open3d).

    python tools/fit_room_pointcloud.py ../shared/data/pointcloud/office1.pcd --up=-y \
        --out results/calib/office1_scan.yaml                                 # + .png and .md

--up is the sensor frame's up axis: -y for a camera optical frame (x right, y down, z forward), z for a ROS
body frame. Exit code 2 on bad input (missing or unreadable file, no floor found).
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.calib.io import check_outputs
from ssbl_pb.calib.pointcloud import analyse, load_points, parse_up, scan_figure, scan_yaml
from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, run
from ssbl_pb.files import write_text, write_yaml


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scan", type=Path, help="PLY or PCD point cloud (metres)")
    ap.add_argument("--up", default="-y", help="sensor up axis: -y (optical frame, default), z, ...")
    ap.add_argument("--out", type=Path, required=True, help="YAML to write (+ .png and .md beside it)")
    ap.add_argument("--distance", type=float, default=0.02, help="RANSAC inlier distance (m)")
    ap.add_argument("--min-floor-share", type=float, default=0.02, help="smallest share of points for the floor")
    ap.add_argument("--seed", type=int_at_least(0), default=0)
    args = ap.parse_args(argv)
    check_outputs(args.out, (".png", ".md"))
    up = parse_up(args.up)
    pts = load_points(args.scan)
    scan = analyse(pts, up, min_floor_share=args.min_floor_share, distance=args.distance, seed=args.seed,
                   where=str(args.scan))
    data = scan_yaml(scan, str(args.scan))
    write_yaml(args.out, data, header=f"RANSAC planes of {args.scan} (up axis {args.up})")
    scan_figure(pts, scan, up, args.out.with_suffix(".png"))
    command = command_line("tools/fit_room_pointcloud.py", argv)
    tilt = f"**{scan.tilt_deg:.2f} deg**"
    if scan.pitch_deg is not None:
        tilt += f" (pitch {scan.pitch_deg:.2f} deg down, roll {scan.roll_deg:.2f} deg)"
    lines = [f"# Point-cloud room fit: {args.scan.name}", "", f"Command: `{command}`", "",
             f"{len(pts)} finite points. Camera height above the floor **{scan.camera_height:.3f} m**, tilt {tilt}.",
             "", "| plane | normal | distance (m) | share | inlier RMS (m) |", "|---|---|---|---|---|"]
    for p in scan.planes:
        lines.append(f"| {p.kind} | {', '.join(f'{v:+.3f}' for v in p.normal)} | {p.d:.3f} | {p.share:.3f} | "
                     f"{p.rms:.4f} |")
    lines += ["", "Room extents (m): " + ", ".join(f"{k} {v:.2f}" for k, v in scan.room_extent.items())]
    write_text(args.out.with_suffix(".md"), "\n".join(lines) + "\n")
    print(f"{args.out}: camera height {scan.camera_height:.3f} m, tilt {scan.tilt_deg:.2f} deg; extents "
          + ", ".join(f"{k} {v:.2f} m" for k, v in scan.room_extent.items()))
    return 0


if __name__ == "__main__":
    run(main)
