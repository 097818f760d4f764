"""Import a ROS map_server map (PGM + YAML) and write the room YAML (WorldParams room_size + map <- room).

    python tools/import_map.py ../shared/data/maps/willow-full.yaml --region 14.5 22 20.5 27.5 \
        --out results/calib/room.yaml                                   # + room.png

The room frame is centred on the room with the map image's axes; deploy maps env positions to the map with
``ssbl_pb.calib.room_map.room_to_map(xy, yaml["map_to_room"])``. Exit code 2 on bad input.
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.calib.io import write_yaml
from ssbl_pb.calib.room_map import extract_room, read_map, room_figure, room_yaml
from ssbl_pb.cli import ArgumentParser, run
from ssbl_pb.files import check_output_path


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("map", type=Path, help="map_server YAML (image, resolution, origin, thresholds, negate)")
    ap.add_argument("--out", type=Path, required=True, help="room YAML to write (+ a PNG beside it)")
    ap.add_argument("--region", type=float, nargs=4, metavar=("XMIN", "YMIN", "XMAX", "YMAX"),
                    help="box of the map (metres, map frame) that holds the room")
    ap.add_argument("--seed", type=float, nargs=2, metavar=("X", "Y"),
                    help="a free point inside the room (map frame); its connected free space is the room")
    ap.add_argument("--door-width", type=float, default=0.9, help="openings narrower than this close (m)")
    ap.add_argument("--size-from", choices=("bounds", "free"), default="bounds",
                    help="room_size from the wall-to-wall bounds or the largest furniture-free rectangle")
    args = ap.parse_args(argv)
    check_output_path(args.out, is_dir=False)
    if args.region is None and args.seed is None:
        ap.error("give --region and/or --seed")
    m = read_map(args.map)
    seed = tuple(args.seed) if args.seed else None
    region = tuple(args.region) if args.region else None
    room = extract_room(m, seed, region, args.door_width, args.size_from)
    data = room_yaml(m, room, seed, region)
    write_yaml(args.out, data, header=f"room cut from {args.map}; frame centred on the room, map axes")
    room_figure(m, room, args.out.with_suffix(".png"))
    print(f"{args.out}: room_size {data['world']['room_size']} m, centre {list(room.centre)} (map frame), "
          f"free rectangle {room.free_rect[2] - room.free_rect[0]:.1f} x {room.free_rect[3] - room.free_rect[1]:.1f}"
          f" m, free fraction {room.free_fraction:.2f}")
    return 0


if __name__ == "__main__":
    run(main)
