"""Human-motion statistics from ETH/UCY (obsmat + groups.txt) against what the social force model produces.

Real statistics, per scene and pooled:

* group distance: centre-to-centre distance between the members of an annotated group and their nearest
  fellow member, per frame (ETH/UCY groups walk together; they are not conversation F-formations).
* walking speed: |v| of every person-frame with |v| > ``moving`` (0.3 m/s), from obsmat's velocity columns.
* stranger distance: for each pair of people not in a common group who came within ``near`` (3 m) of each
  other, their closest approach; its lower quartile is taken as the personal radius (3 in 4 passing
  strangers keep at least that distance).

Simulated: the same three from ``humans.Group`` (the env's SFFM members) with a robot walking to the
group's free slot: neighbour distances within the group, members' speeds while they move, and the
closest member-robot distance (the robot is the only stranger there).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..cli import progress as bar
from ..core.humans import Group
from ..core.layouts import paper_layout
from ..params import FORMATIONS, CalibrationError, RobotParams, SocialParams

SCENES = ("ewap_seq_eth", "ewap_seq_hotel", "ucy_zara01", "ucy_zara02", "ucy_students03")


@dataclasses.dataclass
class Scene:
    """One dataset: rows of (frame, id, x, y, vx, vy) and the groups as sets of ids."""

    name: str
    rows: np.ndarray
    groups: list[set[int]]


def load_scene(folder: str | Path) -> Scene:
    """Read obsmat.txt (or .gz) and groups.txt; errors name the file."""
    folder = Path(folder)
    obs = folder / "obsmat.txt"
    if not obs.is_file():
        obs = folder / "obsmat.txt.gz"
    if not obs.is_file():
        raise CalibrationError(f"{folder}: no obsmat.txt(.gz)")
    try:
        raw = np.loadtxt(obs, ndmin=2)
    except ValueError as exc:
        raise CalibrationError(f"{obs}: not a numeric obsmat table ({exc})") from exc
    if raw.shape[1] != 8:
        raise CalibrationError(f"{obs}: {raw.shape[1]} columns; obsmat has 8 (frame id x z y vx vz vy)")
    rows = raw[:, [0, 1, 2, 4, 5, 7]]
    groups: list[set[int]] = []
    gpath = folder / "groups.txt"
    if gpath.is_file():
        for line in gpath.read_text().splitlines():
            ids = {int(float(v)) for v in line.split()}
            if len(ids) >= 2:
                groups.append(ids)
    return Scene(folder.name, rows, groups)


def _frames(rows: np.ndarray) -> dict[int, np.ndarray]:
    order = np.argsort(rows[:, 0], kind="stable")
    rows = rows[order]
    keys, starts = np.unique(rows[:, 0], return_index=True)
    ends = np.append(starts[1:], len(rows))
    return {int(k): rows[s:e] for k, s, e in zip(keys, starts, ends, strict=True)}


def scene_stats(scene: Scene, moving: float = 0.3, near: float = 3.0) -> dict[str, np.ndarray]:
    """Group distances, walking speeds and stranger closest approaches (metres, m/s) of one scene."""
    rows = scene.rows
    speed = np.hypot(rows[:, 4], rows[:, 5])
    member_of: dict[int, set[int]] = {}
    for gi, g in enumerate(scene.groups):
        for pid in g:
            member_of.setdefault(pid, set()).add(gi)
    group_d: list[float] = []
    closest: dict[tuple[int, int], float] = {}
    for fr in _frames(rows).values():
        if len(fr) < 2:
            continue
        ids = fr[:, 1].astype(int)
        d = np.hypot(fr[:, None, 2] - fr[None, :, 2], fr[:, None, 3] - fr[None, :, 3])
        np.fill_diagonal(d, np.inf)
        same = np.array([[bool(member_of.get(a, set()) & member_of.get(b, set())) for b in ids] for a in ids])
        for i in range(len(ids)):
            if same[i].any():
                group_d.append(float(d[i][same[i]].min()))
        iu, ju = np.nonzero(np.triu(~same & (d < near), 1))
        for i, j in zip(iu, ju, strict=True):
            key = (min(ids[i], ids[j]), max(ids[i], ids[j]))
            closest[key] = min(closest.get(key, math.inf), float(d[i, j]))
    return {"group_distance": np.array(group_d), "walking_speed": speed[speed > moving],
            "stranger_distance": np.array(list(closest.values()))}


def real_stats(root: str | Path, scenes: tuple[str, ...] = SCENES) -> dict[str, dict[str, np.ndarray]]:
    """Per-scene statistics plus "all" (pooled)."""
    root = Path(root)
    out = {}
    for name in scenes:
        out[name] = scene_stats(load_scene(root / name))
    out["all"] = {k: np.concatenate([out[s][k] for s in scenes]) for k in out[scenes[0]]}
    return out


def sim_stats(social: SocialParams, episodes: int = 40, seconds: float = 20.0, dt: float = 0.1,
              robot_speed: float = RobotParams.max_speed, seed: int = 0, progress: bool = False
              ) -> dict[str, np.ndarray]:
    """The same statistics from SFFM groups (2-5 members, all formations) with a robot walking to the slot."""
    rng = np.random.default_rng(seed)
    group_d, speeds, closest = [], [], []
    eps = range(episodes)
    if progress:
        eps = bar(eps, "SFFM episodes", "ep")
    for ep in eps:
        n = 2 + ep % 4
        form = FORMATIONS[(ep // 4) % len(FORMATIONS)]
        g = Group(social, np.zeros(2), paper_layout(form, n, social, rng.uniform(0, 2 * math.pi)))
        theta = rng.uniform(0, 2 * math.pi)
        robot = rng.uniform(3.0, 5.0) * np.array([math.cos(theta), math.sin(theta)])
        slot = g.free_slot(robot)
        dmin = math.inf
        for _ in range(int(seconds / dt)):
            to = slot - robot
            dist = math.hypot(*to)
            if dist > 1e-6:
                robot = robot + to / dist * min(robot_speed * dt, dist)
            g.step(robot, dt)
            slot = g.free_slot(robot)
            pair = np.hypot(g.pos[:, None, 0] - g.pos[None, :, 0], g.pos[:, None, 1] - g.pos[None, :, 1])
            np.fill_diagonal(pair, np.inf)
            group_d.extend(pair.min(axis=1).tolist())
            sp = np.hypot(g.vel[:, 0], g.vel[:, 1])
            speeds.extend(sp[sp > 0.05].tolist())
            dmin = min(dmin, float(np.hypot(*(g.pos - robot).T).min()))
        closest.append(dmin)
    return {"group_distance": np.array(group_d), "walking_speed": np.array(speeds),
            "stranger_distance": np.array(closest)}


def fit_social(real: dict[str, np.ndarray], base: SocialParams | None = None
               ) -> tuple[dict[str, float], list[str]]:
    """SocialParams fields from the pooled real statistics, with the reasons as notes."""
    base = base or SocialParams()
    notes = []
    personal = float(np.percentile(real["stranger_distance"], 25))
    gap = float(np.median(real["group_distance"]))
    speed = float(np.median(real["walking_speed"]))
    fields = {"personal_radius": round(personal, 3), "max_speed": round(speed, 3)}
    notes.append(f"personal_radius = lower quartile of the closest approach of stranger pairs that came within "
                 f"3 m: 3 in 4 pass at least this far apart ({personal:.2f} m; default {base.personal_radius})")
    notes.append(f"max_speed = median walking speed while moving ({speed:.2f} m/s; default {base.max_speed})")
    floor = personal + 0.05
    if gap < floor:
        notes.append(f"min_member_gap: real groups walk {gap:.2f} m apart, inside the fitted personal radius; "
                     f"set to personal_radius + 0.05 = {floor:.2f} m so members do not repel each other")
        gap = floor
    else:
        notes.append(f"min_member_gap = median nearest-member distance in groups ({gap:.2f} m)")
    fields["min_member_gap"] = round(gap, 3)
    if not fields["personal_radius"] < base.social_radius:
        raise CalibrationError(f"fitted personal_radius {personal:.2f} m is not below social_radius "
                               f"{base.social_radius} m")
    return fields, notes


def summary(values: np.ndarray) -> str:
    """"median [q25, q75] (n)"."""
    if len(values) == 0:
        return "- (0)"
    q = np.percentile(values, [25, 50, 75])
    return f"{q[1]:.2f} [{q[0]:.2f}, {q[2]:.2f}] ({len(values)})"
