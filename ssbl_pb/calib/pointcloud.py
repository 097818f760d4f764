"""Room size, camera height and tilt from a depth scan (PLY/PCD) with open3d RANSAC planes.

Planes are found one after another (RANSAC on a voxel-downsampled cloud, inliers removed each time). Those
whose normal is within ``horizontal_deg`` of the sensor's up axis are floor/ceiling/table candidates; the
floor is the horizontal plane farthest below the sensor that holds at least ``min_floor_share`` of the
points (a table top is higher, so it is skipped; the floor may be a small share of a frame). Planes within
``vertical_deg`` of vertical are walls; two walls with opposite normals bound the room along that direction.

The sensor frame's up axis is given as e.g. "-y" (a camera optical frame: x right, y down, z forward) or
"z" (a ROS body frame). Camera height is the distance from the sensor origin to the floor plane; the tilt is
the angle between the floor normal and the up axis, split into pitch (down +) and roll for an optical frame.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import re
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..params import CalibrationError
from .io import save_figure

AXES = {"x": 0, "y": 1, "z": 2}


def parse_up(text: str) -> np.ndarray:
    """"-y" -> (0, -1, 0)."""
    t = text.strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    axis = t.lstrip("+-")
    if axis not in AXES:
        raise CalibrationError(f"up axis {text!r}: expected x, y or z with an optional sign, e.g. -y")
    v = np.zeros(3)
    v[AXES[axis]] = sign
    return v


def _open3d() -> Any:
    """open3d with its log quiet: its warnings (and RPly's) would precede our one-line error."""
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    return o3d


@contextlib.contextmanager
def _captured_output() -> Iterator[list[str]]:
    """What C code prints to stdout/stderr inside the block (RPly writes there directly), as lines of the list."""
    lines: list[str] = []
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as tmp:
        try:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            yield lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            text = re.sub(r"\x1b\[[0-9;]*m", "", tmp.read().decode(errors="replace"))  # no colour codes
            lines += [ln.strip() for ln in text.splitlines() if ln.strip()]


def load_points(path: str | Path) -> np.ndarray:
    """Finite XYZ points (N, 3) from a PLY/PCD file; ``CalibrationError`` names the file."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: file not found")
    if path.suffix.lower() not in (".ply", ".pcd", ".xyz", ".pts"):
        raise CalibrationError(f"{path}: expected a .ply or .pcd point cloud")
    o3d = _open3d()
    with _captured_output() as said:
        pcd = o3d.io.read_point_cloud(str(path))
    pts = np.asarray(pcd.points)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) < 100:
        why = f" ({'; '.join(said)})" if said else ""
        raise CalibrationError(f"{path}: {len(pts)} finite points; not a readable scan{why}")
    return pts


@dataclasses.dataclass
class Plane:
    """n . p + d = 0 with unit n; ``share`` of all points; ``kind`` floor/horizontal/wall/other."""

    normal: np.ndarray
    d: float
    share: float
    kind: str
    rms: float  # inlier distance RMS (m)


@dataclasses.dataclass
class RoomScan:
    """What the scan says about the room and the sensor."""

    planes: list[Plane]
    floor: Plane
    camera_height: float
    tilt_deg: float  # angle between the floor normal and the up axis
    pitch_deg: float | None  # for an optical frame ("-y" up): downward tilt of the optical axis
    roll_deg: float | None
    room_extent: dict[str, float]  # "walls <i>-<j>": distance between opposite walls; "floor <a>": floor extent
    wall_distances: list[float]  # horizontal distance from the sensor to each wall plane


def find_planes(pts: np.ndarray, max_planes: int = 8, distance: float = 0.02, voxel: float = 0.03,
                min_share: float = 0.01, seed: int = 0) -> list[tuple[np.ndarray, float, float, float]]:
    """Up to ``max_planes`` planes (normal, d, share of points, inlier RMS) by sequential RANSAC."""
    o3d = _open3d()
    o3d.utility.random.seed(seed)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pcd = pcd.voxel_down_sample(voxel) if voxel > 0 else pcd
    rest = pcd
    total = len(pcd.points)
    out = []
    for _ in range(max_planes):
        if len(rest.points) < max(50, min_share * total):
            break
        model, idx = rest.segment_plane(distance_threshold=distance, ransac_n=3, num_iterations=1000)
        if len(idx) < min_share * total:
            break
        a, b, c, d = model
        n = np.array([a, b, c])
        norm = np.linalg.norm(n)
        n, d = n / norm, d / norm
        inl = np.asarray(rest.select_by_index(idx).points)
        # least-squares refinement on the inliers
        centroid = inl.mean(axis=0)
        _, _, vt = np.linalg.svd(inl - centroid, full_matrices=False)
        n2 = vt[2] * (1.0 if vt[2] @ n > 0 else -1.0)
        d2 = -float(n2 @ centroid)
        rms = float(np.sqrt(np.mean((inl @ n2 + d2) ** 2)))
        out.append((n2, d2, len(idx) / total, rms))
        rest = rest.select_by_index(idx, invert=True)
    return out


def merge_planes(planes: list[Plane], angle_deg: float = 5.0, gap: float = 0.3) -> list[Plane]:
    """Merge planes of one kind that are parallel and less than ``gap`` apart (share-weighted).

    Structured-light sensors quantise far depth into layers a few cm apart, so one far wall comes out of
    RANSAC as several thin parallel slices; they are one wall.
    """
    out: list[Plane] = []
    for p in sorted(planes, key=lambda q: -q.share):
        for q in out:
            if (q.kind == p.kind and p.normal @ q.normal > math.cos(math.radians(angle_deg))
                    and abs(p.d - q.d) < gap):
                w = q.share + p.share
                q.d = (q.d * q.share + p.d * p.share) / w
                q.rms = math.sqrt((q.rms ** 2 * q.share + p.rms ** 2 * p.share + (p.d - q.d) ** 2 * p.share) / w)
                q.share = w
                break
        else:
            out.append(dataclasses.replace(p))
    return out


def analyse(pts: np.ndarray, up: np.ndarray, horizontal_deg: float = 20.0, vertical_deg: float = 15.0,
            min_floor_share: float = 0.02, max_planes: int = 12, distance: float = 0.02, seed: int = 0,
            where: str = "scan") -> RoomScan:
    """Classify RANSAC planes and derive the camera height, tilt and room extents."""
    raw = find_planes(pts, max_planes, distance, seed=seed)
    planes: list[Plane] = []
    for n, d, share, rms in raw:
        if n @ up < 0:  # orient horizontal normals up, walls toward the sensor
            n, d = -n, -d
        c = float(n @ up)
        if c > math.cos(math.radians(horizontal_deg)):
            kind = "horizontal"
        elif abs(c) < math.sin(math.radians(vertical_deg)):
            kind = "wall"
            if d < 0:  # n . 0 + d = d: positive when the sensor is on the normal's side
                n, d = -n, -d
        else:
            kind = "other"
        planes.append(Plane(n, float(d), share, kind, rms))
    planes = merge_planes(planes)
    # the sensor is at height d above a horizontal plane with an upward normal
    floors = [p for p in planes if p.kind == "horizontal" and p.d > 0 and p.share >= min_floor_share]
    if not floors:
        raise CalibrationError(f"{where}: no floor plane found (no horizontal plane below the sensor with "
                               f">= {min_floor_share:.0%} of the points; check --up)")
    floor = max(floors, key=lambda p: p.d)
    floor.kind = "floor"
    u = floor.normal
    tilt = math.degrees(math.acos(float(np.clip(u @ up, -1.0, 1.0))))
    pitch = roll = None
    if np.allclose(up, [0.0, -1.0, 0.0]):  # optical frame: up = (-cos p sin r, -cos p cos r, -sin p)
        pitch = math.degrees(math.asin(float(np.clip(-u[2], -1.0, 1.0))))
        roll = math.degrees(math.atan2(-u[0], -u[1]))
    walls = [p for p in planes if p.kind == "wall"]
    extent: dict[str, float] = {}
    for i in range(len(walls)):
        for j in range(i + 1, len(walls)):
            if walls[i].normal @ walls[j].normal < -math.cos(math.radians(10.0)):
                extent[f"walls {i}-{j}"] = round(walls[i].d + walls[j].d, 3)
    # floor extent along the first wall's normal (or the sensor's forward direction) and across it
    fin = pts[np.abs(pts @ u + floor.d) < distance]
    ref = walls[0].normal if walls else np.array([0.0, 0.0, 1.0])
    e1 = ref - (ref @ u) * u
    e1 /= max(np.linalg.norm(e1), 1e-12)
    e2 = np.cross(u, e1)
    for name, e in (("floor along wall 0 normal" if walls else "floor forward", e1), ("floor across", e2)):
        if len(fin) > 10:
            lo, hi = np.percentile(fin @ e, [1, 99])
            extent[name] = round(float(hi - lo), 3)
    return RoomScan(planes, floor, float(floor.d), tilt, pitch, roll, extent, [float(w.d) for w in walls])


def synthetic_room(size: tuple[float, float] = (6.0, 4.0), height: float = 1.15, pitch_deg: float = 15.0,
                   roll_deg: float = 2.0, noise: float = 0.005, n: int = 60000, seed: int = 0,
                   cam_xy: tuple[float, float] = (1.0, 0.0)) -> np.ndarray:
    """Points (optical frame) of a box room seen by a camera at ``height``, pitched down and rolled.

    Room frame: x forward, y left, z up, floor 0, walls at x = +-size/2, y = +-size/2 (2.5 m high); the
    camera at ``cam_xy`` looks along +x. Half the points are on a desk-like clutter so the floor is a minority.
    """
    rng = np.random.default_rng(seed)
    sx, sy = size
    k = n // 8
    floor = np.c_[rng.uniform(-sx / 2, sx / 2, k), rng.uniform(-sy / 2, sy / 2, k), np.zeros(k)]
    back = np.c_[np.full(2 * k, sx / 2), rng.uniform(-sy / 2, sy / 2, 2 * k), rng.uniform(0, 2.5, 2 * k)]
    left = np.c_[rng.uniform(-sx / 2, sx / 2, k), np.full(k, sy / 2), rng.uniform(0, 2.5, k)]
    right = np.c_[rng.uniform(-sx / 2, sx / 2, k), np.full(k, -sy / 2), rng.uniform(0, 2.5, k)]
    m = n - 5 * k  # clutter: boxes of random sizes standing on the floor
    clutter = np.c_[rng.uniform(0, sx / 2, m), rng.uniform(-sy / 2, sy / 2, m), rng.uniform(0.3, 1.4, m)]
    clutter[:, 2] = np.round(clutter[:, 2] * 5) / 5  # a few table-top heights, smaller than the floor each
    world = np.concatenate([floor, back, left, right, clutter])
    world += rng.normal(0, noise, world.shape)
    # optical frame <- room frame: the camera rotation as in PinholeCamera (pitch down +, roll)
    t, f = math.radians(pitch_deg), math.radians(roll_deg)
    r0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    ry = np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])
    rx = np.array([[1, 0, 0], [0, math.cos(f), -math.sin(f)], [0, math.sin(f), math.cos(f)]])
    r = ry @ rx @ r0  # optical -> room
    centre = np.array([cam_xy[0], cam_xy[1], height])
    cam = (world - centre) @ r
    return cam[cam[:, 2] > 0.3]  # in front of the camera only


def scan_yaml(scan: RoomScan, source: str) -> dict:
    """The YAML written by tools/fit_room_pointcloud.py: camera pose fields and the room's extents."""
    out: dict = {"source": source, "camera_height": round(scan.camera_height, 4),
                 "tilt_deg": round(scan.tilt_deg, 3)}
    if scan.pitch_deg is not None and scan.roll_deg is not None:
        out.update(camera_pitch_deg=round(scan.pitch_deg, 3), camera_roll_deg=round(scan.roll_deg, 3))
    out["room_extent"] = {k: float(v) for k, v in scan.room_extent.items()}
    out["planes"] = [{"kind": p.kind, "normal": [round(float(v), 4) for v in p.normal], "d": round(p.d, 4),
                      "share": round(p.share, 4), "rms": round(p.rms, 4)} for p in scan.planes]
    return out


def scan_figure(pts: np.ndarray, scan: RoomScan, up: np.ndarray, path: str | Path, distance: float = 0.03,
                max_points: int = 40000, seed: int = 0) -> Path:
    """Side and top views of the scan in floor coordinates, points coloured by the plane they lie on."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(seed)
    sub = pts[rng.choice(len(pts), min(max_points, len(pts)), replace=False)]
    u = scan.floor.normal
    fwd = np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.5 else np.array([1.0, 0.0, 0.0])
    e1 = fwd - (fwd @ u) * u
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    h = sub @ u + scan.floor.d  # height above the floor
    a, b = sub @ e1, sub @ e2
    colours = np.full(len(sub), "0.75", dtype=object)
    palette = {"floor": "tab:green", "wall": "tab:blue", "horizontal": "tab:orange", "other": "tab:purple"}
    for p in scan.planes:
        colours[np.abs(sub @ p.normal + p.d) < distance] = palette[p.kind]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    ax1.scatter(a, h, s=0.3, c=list(colours))
    ax1.plot([0], [scan.camera_height], "r^", ms=8)
    ax1.set_xlabel("forward (m)")
    ax1.set_ylabel("height above floor (m)")
    ax1.set_title(f"side: camera {scan.camera_height:.3f} m up, tilt {scan.tilt_deg:.2f} deg")
    ax1.set_aspect("equal")
    ax2.scatter(-b, a, s=0.3, c=list(colours))
    ax2.plot([0], [0], "r^", ms=8)
    ax2.set_xlabel("right (m)")
    ax2.set_ylabel("forward (m)")
    ax2.set_title("top (green floor, blue walls, orange other horizontal)")
    ax2.set_aspect("equal")
    return save_figure(path, fig)
