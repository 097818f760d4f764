"""How often MoveNet finds the simulator's person bodies (``urdf/bodies``) in the virtual Pepper's frames
(tools/bench_bodies.py).

``single``: each body alone, straight ahead of the robot at 1-5 m from the base, seen from the front, the side
and the back, at 320x240 (deploy's kQVGA) and 640x480. ``group``: the env's own scenes (``World.reset``: a group
of 2-5 with the robot 2.5-5.5 m from its centre), the robot turned to the centre; every member with at least half
of its body in sight counts. A person is found when one of deploy's MoveNet boxes (``movenet.selected`` with the
built-in pipeline's settings, ``tuning.MOVENET_DEFAULT``) overlaps the box of its pixels (the renderer's
segmentation mask) by IoU >= ``MATCH_IOU``; its score is the best such box's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..env.view.bodies import body_count
from ..env.view.people import PeopleScene
from ..env.view.world import World
from ..params import HumansLook, WorldParams
from ..perception.detection.learned import box_iou
from ..perception.detection.movenet import selected
from ..perception.tracking.tuning import MOVENET_DEFAULT

DISTANCES = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)  # m, base centre to the person
VIEWS = {"front": math.pi, "side": math.pi / 2, "back": 0.0}  # the person's yaw, the robot at the origin facing +x
SIZES = ((320, 240), (640, 480))
MATCH_IOU = 0.3  # a MoveNet box spans the keypoints, from the eyes down: it misses the top of the head
VISIBLE = 0.5  # share of a member's pixels that must show in the group frame (its pixels alone = 1)
THRESHOLDS = (MOVENET_DEFAULT.ssd.score_threshold, MOVENET_DEFAULT.trk.birth_score)  # a box, a track's birth


def mask_box(mask: np.ndarray, body: int) -> tuple[np.ndarray | None, int]:
    """The box (x, y, w, h) px of ``body``'s pixels in a segmentation mask and their count (None: none)."""
    ys, xs = np.nonzero((mask & 0xFFFFFF) == body)
    if len(xs) == 0:
        return None, 0
    return np.array([xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()], dtype=float), len(xs)


def best_score(boxes: np.ndarray, truth: np.ndarray) -> float:
    """Score of the best box (x, y, w, h, score, any further columns) overlapping ``truth`` by ``MATCH_IOU``; 0 if
    none does."""
    boxes = np.asarray(boxes, dtype=float)
    boxes = boxes.reshape(-1, boxes.shape[-1] if boxes.ndim == 2 else 5)[:, :5]
    if len(boxes) == 0:
        return 0.0
    hit = box_iou(boxes, truth[None])[:, 0] >= MATCH_IOU
    return float(boxes[hit, 4].max()) if hit.any() else 0.0


def movenet_detector() -> Callable[[np.ndarray], np.ndarray]:
    """Deploy's MoveNet boxes for RGB frames (``movenet.selected``, the built-in pipeline's settings; needs
    ai-edge-litert and the weights: the tracking extra)."""
    return selected(MOVENET_DEFAULT.ssd, rgb=True)


def single(detect: Callable[[np.ndarray], np.ndarray], bodies: Sequence[int] | None = None,
           distances: Sequence[float] = DISTANCES, sizes: Sequence[tuple[int, int]] = SIZES) -> list[dict[str, Any]]:
    """One row per body, distance, view and frame size: ``score`` of the match (0: not found)."""
    rows = []
    with PeopleScene() as scene:
        for body in range(body_count()) if bodies is None else bodies:
            for d in distances:
                for view, yaw in VIEWS.items():
                    (pid,) = scene.show([[d, 0.0, yaw]], [body])
                    for w, h in sizes:
                        img, mask = scene.render((0.0, 0.0, 0.0), w, h, segmentation=True)
                        truth, _ = mask_box(mask, pid)
                        score = best_score(detect(img), truth) if truth is not None else 0.0
                        rows.append({"body": body, "distance": d, "view": view, "size": f"{w}x{h}",
                                     "score": score})
    return rows


def group(detect: Callable[[np.ndarray], np.ndarray], episodes: int = 20, seed: int = 0,
          sizes: Sequence[tuple[int, int]] = SIZES, appearance: str = "body") -> list[dict[str, Any]]:
    """One row per member at least ``VISIBLE`` in sight in the env's scenes (``episodes`` seeded spawns of 2-5
    members, the robot turned to the group's centre; members drawn as ``appearance``): its ``distance`` (m),
    ``score``, ``visible`` share."""
    rows = []
    world = World(WorldParams(n_humans=5, formation="circular", humans=HumansLook(appearance)))
    try:
        for ep in range(episodes):
            rng = np.random.default_rng(seed + ep)
            n = int(rng.integers(2, 6))
            world.reset(rng, n_humans=n, formation=("vis_a_vis", "l_shape", "side_by_side", "circular")[ep % 4])
            world.set_body_seed(seed + ep)
            x, y, _ = world.base.pose
            cx, cy = world.group.centre
            world.base.pose = np.array([x, y, math.atan2(cy - y, cx - x)])
            world.invalidate()
            for w, h in sizes:
                rows += _group_frame(world, detect, w, h, ep)
    finally:
        world.close()
    return rows


def _group_frame(world: World, detect: Callable[[np.ndarray], np.ndarray], w: int, h: int,
                 ep: int) -> list[dict[str, Any]]:
    img, mask = world.render_first_person(w, h, segmentation=True)
    boxes = detect(img)
    pos, yaw = world.group.pos.copy(), world.group.yaw.copy()
    rows = []
    for i in range(world.group.n):
        truth, shown = mask_box(mask, world.human_ids[i])
        if truth is None:
            continue
        world.group.pos[:] = 100.0  # every other member out of the room: this one's own pixels
        world.group.pos[i] = pos[i]
        world.invalidate()
        _, alone = mask_box(world.render_first_person(w, h, segmentation=True)[1], world.human_ids[i])
        world.group.pos[:], world.group.yaw[:] = pos, yaw
        world.invalidate()
        if shown < VISIBLE * alone:
            continue
        d = float(np.hypot(*(pos[i] - world.base.pose[:2])))
        rows.append({"appearance": world.params.humans.appearance, "episode": ep, "member": i,
                     "distance": round(d, 2), "size": f"{w}x{h}", "visible": round(shown / alone, 2),
                     "score": best_score(boxes, truth)})
    return rows


def recall(rows: list[dict[str, Any]], threshold: float, **where: Any) -> tuple[float, int]:
    """Share of ``rows`` (those matching ``where``) with a score at least ``threshold``, and their count."""
    sel = [r for r in rows if all(r[k] == v for k, v in where.items())]
    return (float(np.mean([r["score"] >= threshold for r in sel])) if sel else math.nan), len(sel)


def markdown(single_rows: list[dict[str, Any]], group_rows: list[dict[str, Any]]) -> str:
    """Tables of recall (at the box threshold / the track birth score) by distance and view, and in groups."""
    lo, hi = THRESHOLDS
    out = [f"Recall of MoveNet on the shipped bodies (score >= {lo:g} / >= {hi:g}, box IoU >= {MATCH_IOU:g})", ""]
    sizes = sorted({r["size"] for r in single_rows}, key=lambda s: int(s.split("x")[0]))
    dists = sorted({r["distance"] for r in single_rows})
    out += ["| frame | view | " + " | ".join(f"{d:g} m" for d in dists) + " |",
            "|---|---|" + "---|" * len(dists)]
    for size in sizes:
        for view in VIEWS:
            cells = [f"{recall(single_rows, lo, size=size, view=view, distance=d)[0]:.0%} / "
                     f"{recall(single_rows, hi, size=size, view=view, distance=d)[0]:.0%}" for d in dists]
            out.append(f"| {size} | {view} | " + " | ".join(cells) + " |")
    if group_rows:
        out += ["", f"In the env's groups (members at least {VISIBLE:.0%} in sight):", ""]
        for look in sorted({r["appearance"] for r in group_rows}):
            for size in sizes:
                r_lo, n = recall(group_rows, lo, size=size, appearance=look)
                r_hi, _ = recall(group_rows, hi, size=size, appearance=look)
                out.append(f"- {look}, {size}: {r_lo:.0%} / {r_hi:.0%} of {n} members")
    return "\n".join(out) + "\n"
