"""Accuracy of ``proxy_facing.estimate_facing`` on rendered QVGA frames of the virtual Pepper (tools/bench_facing.py).

Scenes: the robot at a random heading (the renderer's light is fixed in the world, so the faces' shading varies
with it) and either one person (``single``) 1-5 m away at a bearing inside the view, or two (``occluded``): a
nearer one 1-3.5 m away and a farther one 0.6-2 m behind it, offset sideways so that 25-90 % of its width shows
(were both face-on). Every person's facing is uniform over 360 deg and each is drawn in a random palette
colour (``world.HUMAN_COLOURS``). Then the env's own scenes (``group``): ``World.reset`` spawns a group of 2-5
(members on the o-space circle facing its centre) and the robot 2.5-5.5 m from the centre, which it faces (+-14
deg). Boxes come from deploy's detector (``deploy.perceive.make_detector("colour")``) and its ``facing()``,
matched to people by colour; a box cut by the image's side is dropped after, as deploy does.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..deploy.perceive import make_detector
from ..env.view.world import World
from ..perception.detection.facing import phi_of, wrap
from ..urdf import HUMAN_COLOURS

BANDS = ((1.0, 2.0), (2.0, 3.0), (3.0, 4.0), (4.0, 5.0), (5.0, 7.0))  # m, from the camera to the body axis
CLASSES = (("front", 0.0, 80.0), ("side", 80.0, 100.0), ("back", 100.0, 180.01))  # |true phi|, deg


@dataclasses.dataclass(frozen=True)
class Sample:
    scene: str  # "single", "near" or "far" (the partly hidden one of an occluded pair), "group"
    distance: float  # m
    phi: float  # true, rad
    est: float  # rad, NaN: no estimate
    std: float
    est_abs: float
    abs_std: float
    front: float
    detected: bool  # a whole box of the person's colour was found


def place(world: Any, heading: float, people: list[tuple[int, float, float, float]]) -> np.ndarray:
    """The robot 2.5 m from the room's centre facing ``heading`` across it; ``people`` as (member, distance from
    the camera, bearing from the optical axis, phi). Other members stand behind the robot. Returns the camera's
    ground position."""
    back = -2.5 * np.array([math.cos(heading), math.sin(heading)])  # the scene stays inside the 10 m room
    world.base.pose = np.array([back[0], back[1], heading])
    cam = back + world.robot_params.camera_forward * np.array([math.cos(heading), math.sin(heading)])
    used = {m for m, *_ in people}
    for k in range(world.group.n):
        if k not in used:
            world.group.pos[k] = back - (1.5 + 0.6 * k) * np.array([math.cos(heading), math.sin(heading)])
            world.group.yaw[k] = 0.0
    for m, d, bearing, phi in people:
        pos = cam + d * np.array([math.cos(heading + bearing), math.sin(heading + bearing)])
        world.group.pos[m] = pos
        world.group.yaw[m] = math.atan2(cam[1] - pos[1], cam[0] - pos[0]) + phi
    world.invalidate()
    return cam


def run_bench(frames: int = 400, seed: int = 0, width: int = 320, height: int = 240,
              progress: Any = None) -> tuple[list[Sample], list[float]]:
    """``frames`` frames of each scene (single, occluded, group); ``progress(n)`` is told of each frame. Returns
    the samples and the seconds the detector's ``facing()`` took on each frame."""
    import time

    rng = np.random.default_rng(seed)
    world = World()
    detect, _ = make_detector("colour")
    half_fov = math.radians(world.robot_params.camera_hfov_deg) / 2
    out: list[Sample] = []
    seconds: list[float] = []

    def measure(truth: list[tuple[str, int, float, float]]) -> None:
        """Render, detect, read the facing and score ``truth``: (scene, member, distance, phi) rows."""
        rgb, _ = world.render_first_person(width, height)
        boxes = detect(rgb)
        t0 = time.perf_counter()
        fac = detect.facing()  # of every box: a person cut by the image's side can still hide another
        seconds.append(time.perf_counter() - t0)
        keep = (boxes[:, 0] > 1) & (boxes[:, 0] + boxes[:, 2] < width - 1)  # as deploy: whole boxes only
        for name, m, dist, phi in truth:
            j = np.flatnonzero((detect.last_colours == m) & keep)
            if not len(j):
                out.append(Sample(name, dist, phi, *([math.nan] * 5), False))
                continue
            i = int(j[0])
            out.append(Sample(name, dist, phi, float(fac.phi[i]), float(fac.std[i]), float(fac.phi_abs[i]),
                              float(fac.abs_std[i]), float(fac.front[i]), True))
        if progress is not None:
            progress(1)

    try:
        for scene in ("single", "occluded"):
            world.reset(np.random.default_rng(0), n_humans=len(HUMAN_COLOURS))
            for _ in range(frames):
                heading = rng.uniform(-math.pi, math.pi)
                members = rng.permutation(len(HUMAN_COLOURS))[:2]
                d = rng.uniform(1.0, 5.0) if scene == "single" else rng.uniform(1.0, 3.5)
                room = half_fov - math.atan2(0.30, d) - 0.02  # the whole torso inside the view
                bearing = rng.uniform(-room, room)
                people = [(int(members[0]), d, bearing, rng.uniform(-math.pi, math.pi))]
                if scene == "occluded":  # the farther one shows 25-90 % of its width (were both seen face-on)
                    d2 = d + rng.uniform(0.6, 2.0)
                    near, far = math.atan2(0.23, d), math.atan2(0.23, d2)  # torsos' angular half-widths
                    side = near + far * (2 * rng.uniform(0.25, 0.9) - 1)
                    people.append((int(members[1]), d2, bearing + rng.choice([-1.0, 1.0]) * side,
                                   rng.uniform(-math.pi, math.pi)))
                place(world, heading, people)
                names = ["single"] if scene == "single" else ["near", "far"]
                measure([(n, m, dist, float(wrap(phi))) for n, (m, dist, _, phi) in zip(names, people, strict=True)])
        for _ in range(frames):  # the env's own groups: members face the o-space centre, the robot looks at it
            world.reset(rng, n_humans=int(rng.integers(2, len(HUMAN_COLOURS) + 1)))
            pose = world.base.pose.copy()
            centre = world.group.centre0
            pose[2] = math.atan2(centre[1] - pose[1], centre[0] - pose[0]) + rng.uniform(-0.25, 0.25)
            world.base.pose = pose
            world.invalidate()
            cam = pose[:2] + world.robot_params.camera_forward * np.array([math.cos(pose[2]), math.sin(pose[2])])
            measure([("group", m, float(np.hypot(*(world.group.pos[m] - cam))),
                      phi_of(world.group.pos[m], float(world.group.yaw[m]), cam)) for m in range(world.group.n)])
    finally:
        world.close()
    return out, seconds


def summarise(samples: list[Sample]) -> dict[str, Any]:
    """Error statistics (deg) by scene, class of true |phi| and distance band."""

    def stats(rows: list[Sample]) -> dict[str, Any]:
        seen = [s for s in rows if s.detected]
        ok = [s for s in seen if math.isfinite(s.est)]
        err = np.degrees(np.abs(wrap(np.array([s.est - s.phi for s in ok])))) if ok else np.zeros(0)
        err_abs = np.degrees(np.abs(np.array([s.est_abs - abs(s.phi) for s in seen if math.isfinite(s.est_abs)])))
        within = [abs(float(wrap(s.est - s.phi))) <= 2 * s.std for s in ok]
        front_ok = [(s.front >= 0.5) == (abs(s.phi) < math.pi / 2) for s in seen if math.isfinite(s.front)]

        def pct(a: np.ndarray, q: float) -> float | None:
            return round(float(np.percentile(a, q)), 1) if len(a) else None

        return {"n": len(rows), "detected": len(seen), "nan_rate": round(1 - len(ok) / len(seen), 3) if seen else None,
                "median_deg": pct(err, 50), "p90_deg": pct(err, 90), "abs_median_deg": pct(err_abs, 50),
                "abs_p90_deg": pct(err_abs, 90), "within_2std": round(float(np.mean(within)), 3) if within else None,
                "front_back_right": round(float(np.mean(front_ok)), 3) if front_ok else None}

    res: dict[str, Any] = {}
    for scene in ("single", "near", "far", "group"):
        rows = [s for s in samples if s.scene == scene]
        if not rows:
            continue
        res[scene] = {}
        for name, lo, hi in CLASSES:
            cls = [s for s in rows if lo <= math.degrees(abs(s.phi)) < hi]
            res[scene][name] = {"all": stats(cls)}
            for a, b in BANDS:
                res[scene][name][f"{a:g}-{b:g} m"] = stats([s for s in cls if a <= s.distance < b + 1e-9])
    return res


def markdown(summary: dict[str, Any], command: str) -> str:
    """The summary as Markdown tables (one per scene)."""
    lines = ["# Facing from the virtual Pepper's frames", "", f"`{command}`", "",
             "Error: |phi estimated - phi true| (deg) where phi is given; NaN: phi withheld (posterior spread > "
             "max_std); |phi|: the folded estimate ``phi_abs``; 2 std: share of errors within twice the reported "
             "std; front/back: ``front >= 0.5`` agrees with |phi| < 90 deg.", ""]
    titles = {"single": "One person", "near": "Occluded pair: the nearer person",
              "far": "Occluded pair: the farther, partly hidden person",
              "group": "The env's groups (2-5 members facing the o-space centre; undetected: out of view or hidden)"}
    for scene, classes in summary.items():
        lines += [f"## {titles[scene]}", "", "| true phi | distance | n | detected | NaN | median | p90 | "
                  "abs median | abs p90 | within 2 std | front/back right |", "|" + "---|" * 11]
        for name, lo, hi in CLASSES:
            for band, s in classes[name].items():
                cells = [s[k] for k in ("n", "detected", "nan_rate", "median_deg", "p90_deg", "abs_median_deg",
                                        "abs_p90_deg", "within_2std", "front_back_right")]
                cells = ["-" if c is None else (f"{c:.0%}" if k in (2, 7, 8) else str(c)) for k, c in enumerate(cells)]
                label = f"{name} ({lo:g}-{min(hi, 180):g} deg)" if band == "all" else ""
                lines.append(f"| {label} | {band} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)
