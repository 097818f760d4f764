"""Draw a deploy run's paths: the robot's and the tracked humans' on the room's occupancy map (``--map``) or, without
one, on a metric grid of the odometry frame (like the paper's Fig. 1 right).

    python -m ssbl_pb.deploy.plot runs/deploy1                  # redraws runs/deploy1/paths.png from log.jsonl
    python -m ssbl_pb.deploy.plot runs/deploy1 --out paths2.png

Drawn with OpenCV (already loaded for detection), so a run that ends on a fault still draws it in milliseconds.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..calib.io import write_image
from ..cli import ArgumentParser, run
from ..errors import UserError
from ..files import check_output_path
from .frames import inverse, load_room, transform_points
from .log import LOG, PATHS, RUN, SUMMARY, read_log
from .robot import compose

COLOURS = [(48, 160, 60), (200, 100, 50), (30, 130, 230), (160, 70, 150), (40, 40, 210), (120, 120, 0)]  # BGR
WIDTH = 900  # px, the figure's size along its longer side


def paths(rows: list[dict[str, Any]]) -> tuple[np.ndarray, dict[int, list[tuple[np.ndarray, bool]]]]:
    """The robot's room-frame poses (N, 3) and each human's room-frame points with their ``seen`` flags."""
    if not rows:
        return np.zeros((0, 3)), {}
    first = rows[0]
    odom0 = np.array([first["odom_x"], first["odom_y"], first["odom_yaw"]])
    room_from_odom = compose(np.asarray(first["room_pose"], dtype=float), inverse(odom0))
    robot = np.array([r["room_pose"] for r in rows], dtype=float)
    humans: dict[int, list[tuple[np.ndarray, bool]]] = {}
    for r in rows:
        for h in r.get("humans", []):
            xy = transform_points(room_from_odom, np.array([[h["x"], h["y"]]]))[0]
            humans.setdefault(int(h["id"]), []).append((xy, bool(h.get("seen", True))))
    return robot, humans


def draw(folder: str | Path, out: str | Path | None = None) -> Path:
    """Write ``paths.png`` (or ``out``) for the run in ``folder``; returns the path."""
    folder = Path(folder)
    rows = read_log(folder)
    info = json.loads((folder / RUN).read_text()) if (folder / RUN).is_file() else {}
    summary = json.loads((folder / SUMMARY).read_text()) if (folder / SUMMARY).is_file() else {}
    robot, humans = paths(rows)
    room = load_room(info["map"]) if info.get("map") else None
    pts = np.concatenate([robot[:, :2].reshape(-1, 2)] + [np.array([p for p, _ in v]) for v in humans.values()])
    if room is not None:  # to the map frame, and the whole room in view
        robot = np.array([compose(room.map_to_room, q) for q in robot]).reshape(-1, 3)
        humans = {k: [(transform_points(room.map_to_room, p[None])[0], s) for p, s in v] for k, v in humans.items()}
        sx, sy = room.room_size
        corners = np.array([[-sx / 2, -sy / 2], [sx / 2, -sy / 2], [-sx / 2, sy / 2], [sx / 2, sy / 2]])
        pts = transform_points(room.map_to_room, np.concatenate([pts, corners]))
    lo, hi = (pts.min(axis=0) - 1.5, pts.max(axis=0) + 1.5) if len(pts) else (np.full(2, -3.0), np.full(2, 3.0))
    scale = WIDTH / max(float(np.max(hi - lo)), 1.0)  # px per metre
    w, h = (int(math.ceil(v * scale)) for v in hi - lo)

    def px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.round(np.column_stack([(xy[:, 0] - lo[0]) * scale, (hi[1] - xy[:, 1]) * scale])).astype(np.int32)

    img = np.full((h, w, 3), 255, np.uint8)
    if room is not None:
        gx, gy = np.meshgrid(lo[0] + (np.arange(w) + 0.5) / scale, hi[1] - (np.arange(h) + 0.5) / scale)
        uv = np.floor(room.grid.map_to_pixel(np.column_stack([gx.ravel(), gy.ravel()])) + 0.5).astype(int)
        gh, gw = room.grid.shape
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < gw) & (uv[:, 1] >= 0) & (uv[:, 1] < gh)
        state = np.full(len(uv), -1, np.int8)
        state[inside] = room.grid.grid[uv[inside, 1], uv[inside, 0]]
        img[:] = np.select([state == 0, state == 1], [255, 0], 170).reshape(h, w, 1).astype(np.uint8)
    else:
        for x in range(int(math.floor(lo[0])), int(math.ceil(hi[0])) + 1):
            cv2.line(img, (int((x - lo[0]) * scale), 0), (int((x - lo[0]) * scale), h), (225, 225, 225), 1)
        for y in range(int(math.floor(lo[1])), int(math.ceil(hi[1])) + 1):
            cv2.line(img, (0, int((hi[1] - y) * scale)), (w, int((hi[1] - y) * scale)), (225, 225, 225), 1)
    for k, (hid, track) in enumerate(sorted(humans.items())):
        colour = COLOURS[k % len(COLOURS)]
        q = px(np.array([p for p, _ in track]))
        cv2.polylines(img, [q], False, colour, 2, cv2.LINE_AA)
        for (_, seen), c in zip(track, q, strict=True):
            if not seen:
                cv2.circle(img, tuple(int(v) for v in c), 2, (200, 200, 200), -1)
        cv2.circle(img, tuple(int(v) for v in q[-1]), max(3, int(0.28 * scale)), colour, 2, cv2.LINE_AA)
        cv2.putText(img, f"#{hid}", tuple(int(v) for v in q[-1] + 6), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1)
    if len(robot):
        q = px(robot[:, :2])
        cv2.polylines(img, [q], False, (40, 40, 40), 2, cv2.LINE_AA)
        cv2.circle(img, tuple(int(v) for v in q[0]), 6, (40, 40, 40), 2, cv2.LINE_AA)
        end, yaw = robot[-1, :2], robot[-1, 2]
        tip = px(end + 0.4 * np.array([math.cos(yaw), math.sin(yaw)]))[0]
        cv2.arrowedLine(img, tuple(int(v) for v in q[-1]), tuple(int(v) for v in tip), (0, 0, 200), 2, cv2.LINE_AA)
    frame = "map frame" if room is not None else "odometry frame"
    label = f"{summary.get('outcome', 'running')}, {len(rows)} ticks; robot black (start o, end arrow), {frame}"
    cv2.putText(img, label, (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.line(img, (8, h - 12), (8 + int(scale), h - 12), (0, 0, 0), 2)
    cv2.putText(img, "1 m", (12 + int(scale), h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
    return write_image(out or folder / PATHS, img)


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("dir", type=Path, help="a deploy log folder (python -m ssbl_pb.deploy --log-dir)")
    ap.add_argument("--out", type=Path, help="PNG to write (default DIR/paths.png)")
    args = ap.parse_args(argv)
    if not (args.dir / LOG).is_file():
        raise UserError(f"{args.dir}: no {LOG}; expected a folder written by python -m ssbl_pb.deploy --log-dir")
    if args.out is not None:
        check_output_path(args.out, "--out", is_dir=False)
    print(draw(args.dir, args.out))
    return 0


if __name__ == "__main__":
    run(main)
