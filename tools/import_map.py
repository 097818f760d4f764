"""Import a ROS map_server map (PGM + YAML) and write the room YAML (WorldParams room_size + map <- room + the
room's obstacles: every cell inside its walls that is not its free space, merged into boxes).

    python tools/import_map.py ../shared/data/maps/willow-full.yaml --region 14.5 22 20.5 27.5 \
        --out results/calib/room.yaml                                   # + room.png
    python tools/evaluate.py --policy vector --room-yaml results/calib/room.yaml --scenario mixed --out DIR

The room frame is centred on the room with the map image's axes; deploy maps env positions to the map with
``ssbl_pb.calib.room_map.room_to_map(xy, yaml["map_to_room"])``. The simulator trains and evaluates in the room
with its obstacles (scenarios ``@map``, the default with such a YAML). Exit code 2 on bad input.
"""

from __future__ import annotations

import math
from pathlib import Path

from ssbl_pb.calib.io import check_outputs
from ssbl_pb.calib.room_map import extract_room, read_map, room_figure, room_yaml
from ssbl_pb.cli import ArgumentParser, UserError, run
from ssbl_pb.env.rooms.obstacles import box_rows
from ssbl_pb.env.rooms.rooms import Room
from ssbl_pb.env.rooms.spawn import fitting_sizes
from ssbl_pb.files import write_yaml


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
    check_outputs(args.out, (".png",))
    if args.region is None and args.seed is None:
        ap.error("give --region and/or --seed")
    if not (math.isfinite(args.door_width) and args.door_width > 0):
        raise UserError(f"--door-width {args.door_width}: expected a width in metres > 0")
    m = read_map(args.map)
    seed = tuple(args.seed) if args.seed else None
    region = tuple(args.region) if args.region else None
    room = extract_room(m, seed, region, args.door_width, args.size_from)
    data = room_yaml(m, room, seed, region)
    sizes = fits(data)
    span = "-".join(str(n) for n in sorted({sizes[0], sizes[-1]})) if sizes else ""
    holds = (f"holds groups of {span} and the robot" if sizes else
             "holds no group of 2 with the robot: the simulator will refuse it (deploy --map can use it)")
    write_yaml(args.out, data, header=f"room cut from {args.map}; frame centred on the room, map axes")
    room_figure(m, room, args.out.with_suffix(".png"))
    print(f"{args.out}: room_size {data['world']['room_size']} m, centre {list(room.centre)} (map frame), "
          f"free rectangle {room.free_rect[2] - room.free_rect[0]:.1f} x {room.free_rect[3] - room.free_rect[1]:.1f}"
          f" m, free fraction {room.free_fraction:.2f}, {len(data['obstacles']['boxes'])} obstacle boxes; {holds}")
    return 0


def fits(data: dict) -> list[int]:
    """Group sizes the simulator can place in the room with the robot (``env.rooms.spawn.fitting_sizes``)."""
    boxes = [[x, y, sx, sy, math.radians(yaw)] for x, y, sx, sy, yaw in data["obstacles"]["boxes"]]
    size = tuple(data["world"]["room_size"])
    return fitting_sizes(Room(size, box_rows(boxes) if boxes else None, "imported"))


if __name__ == "__main__":
    run(main)
