"""Deploy's MoveNet chain on each shipped body alone (tools/bench_bodies.py): the facing and the range its
keypoints give (``MoveNetFacing.locate``: the feet where the box shows them, else the head, shoulder and hip rows;
no lasers here), against the body's true yaw and distance, in deploy's 320x240 frames, the robot at the origin
facing the body."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..deploy.perceive import make_detector
from ..env.view.bodies import body_count
from ..env.view.people import PeopleScene
from ..params import RobotParams
from ..perception.camera import sim_camera
from .body_detection import DISTANCES, VIEWS

SIZE = (320, 240)  # deploy's kQVGA frames
WITHIN_DEG = 45.0  # a facing this close tells front from side from back


def placed(distances: tuple[float, ...] = DISTANCES) -> list[dict[str, Any]]:
    """One row per body, distance and view: the found person's range error (m, NaN: not found) and facing error
    (deg, signed; NaN: not found or no facing)."""
    detect, _ = make_detector("movenet")
    cam = sim_camera(RobotParams(), *SIZE)
    rows = []
    with PeopleScene() as scene:
        for body in range(body_count()):
            for d in distances:
                for view, yaw in VIEWS.items():
                    scene.show([[d, 0.0, yaw]], [body])
                    img, _ = scene.render((0.0, 0.0, 0.0), *SIZE, segmentation=True)
                    row = {"body": body, "distance": d, "view": view, "range_error": math.nan,
                           "facing_error_deg": math.nan}
                    if len(detect(img)):
                        xy, seen = detect.locate(cam)
                        rng = np.hypot(xy[:, 0], xy[:, 1])
                        if np.isfinite(rng).any():
                            j = int(np.nanargmin(np.abs(rng - d)))
                            row["range_error"] = float(rng[j] - d)
                            if seen is not None and math.isfinite(seen.yaw[j]):
                                row["facing_error_deg"] = math.degrees(math.remainder(seen.yaw[j] - yaw, 2 * math.pi))
                    rows.append(row)
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    """A table by view and distance: the median |facing error| and the share within ``WITHIN_DEG``, the median
    range error (positive: placed too far)."""
    dists = sorted({r["distance"] for r in rows})
    out = [f"Facing (median \\|error\\|, share within {WITHIN_DEG:g} deg) and range (median error) from MoveNet's "
           f"keypoints on the shipped bodies alone, {SIZE[0]}x{SIZE[1]}, no lasers:", "",
           "| view | " + " | ".join(f"{d:g} m" for d in dists) + " |", "|---|" + "---|" * len(dists)]
    for view in VIEWS:
        cells = []
        for d in dists:
            sel = [r for r in rows if r["view"] == view and r["distance"] == d]
            f = np.abs([r["facing_error_deg"] for r in sel])
            e = np.array([r["range_error"] for r in sel])
            faced = f[np.isfinite(f)]
            cells.append(f"{np.median(faced):.0f} deg, {np.mean(faced <= WITHIN_DEG):.0%}; "
                         f"{np.nanmedian(e):+.2f} m" if len(faced) and np.isfinite(e).any() else "-")
        out.append(f"| {view} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"
