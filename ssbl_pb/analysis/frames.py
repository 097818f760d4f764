"""First-person frames for training the camera autoencoders (``tools/collect_frames.py``), and their file.

Episodes are driven by a mix of policies (random, SFFM, straight line, the shipped Vector policy: the original
used an untrained Gaussian policy only, which rarely gets near a group) so the frames cover the whole task, from
far away to standing in the group. Each frame comes with the robot's speed (the CameraSpeed input) and, for
evaluation only, every member's position relative to the robot and its pixel when it is visible.

File layout (``.npz``), N frames of S x S pixels, M = ``MAX_MEMBERS`` member slots (absent members NaN):

=============  ==============  ==============================================================================
key            shape, dtype    meaning
=============  ==============  ==============================================================================
frames         (N, S, S, 3) u1 RGB first-person images
episode        (N,) i4         episode number (frames of an episode are consecutive, in time order)
speed          (N, 2) f4       robot velocity (forward, sideways) / max speed, as the CameraSpeed observation
members_rel    (N, M, 2) f4    members' positions in the robot frame (x forward, y left), metres
members_px     (N, M, 2) f4    the pixel (u, v) of each member's torso centre when in the image, else NaN
policy         (N,) i1         index into ``policies``
policies       (P,) str        the policies' names
camera_hfov    () f4           the camera's horizontal (= vertical) field of view, degrees (optional: files
                               written before it existed are Pepper's 56.3)
=============  ==============  ==============================================================================
"""

from __future__ import annotations

import math
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..agents.rollout import run_episode
from ..core.observation import MAX_MEMBERS, VEL_FORWARD, VEL_LEFT
from ..env.gymenv.approach import make_env
from ..errors import UserError
from ..files import atomic_write
from ..params import RobotParams
from ..perception.camera import sim_camera
from .evaluation import build_policy

KEYS = {"frames": 4, "episode": 1, "speed": 2, "members_rel": 3, "members_px": 3, "policy": 1, "policies": 1}
DEFAULT_POLICIES = ("random", "sffm", "straight", "vector")
TORSO_HEIGHT = 1.14  # m, middle of the proxy's torso box (bench.sim_tracking.ProxyGeometry)


class FramesError(UserError):
    """A frames file is missing, unreadable or of the wrong layout; the message names the file and key."""


def _member_pixels(world, cam, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Members' robot-frame positions (M, 2) and visible torso pixels (M, 2), NaN-padded."""
    rel = np.full((MAX_MEMBERS, 2), np.nan, dtype=np.float32)
    px = np.full((MAX_MEMBERS, 2), np.nan, dtype=np.float32)
    x, y, yaw = world.robot_pose
    c, s = math.cos(yaw), math.sin(yaw)
    d = world.group.pos - (x, y)
    local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    n = len(local)
    rel[:n] = local
    uv = cam.robot_to_pixel(np.column_stack([local, np.full(n, TORSO_HEIGHT)]))
    h, w = seg.shape
    inside = np.isfinite(uv).all(axis=1) & (uv[:, 0] > -0.5) & (uv[:, 0] < w - 0.5) & (uv[:, 1] > -0.5) \
        & (uv[:, 1] < h - 0.5)
    for i in range(n):
        if inside[i] and np.count_nonzero(seg == world.human_ids[i]) >= 2:
            px[i] = uv[i]
    return rel, px


def collect(episodes: int, size: int, seed: int = 0, policies: tuple[str, ...] = DEFAULT_POLICIES,
            scenario: str = "mixed", progress: Callable[[int], None] | None = None,
            camera_hfov_deg: float | None = None) -> dict[str, np.ndarray]:
    """Run ``episodes`` episodes (seeds ``seed``, ``seed + 1``, ...; episode i driven by ``policies[i % P]``),
    seen through Pepper's camera or, with ``camera_hfov_deg``, one of that field of view."""

    if not isinstance(episodes, int) or episodes < 1:
        raise FramesError(f"--episodes {episodes!r}: expected an integer >= 1")
    robot = {} if camera_hfov_deg is None else {"camera_hfov_deg": float(camera_hfov_deg)}
    env = make_env(obs_mode="vector", scenario=scenario, robot=robot)
    world = env.unwrapped.world
    cam = sim_camera(world.robot_params, size, size)
    built = [build_policy(name, env) for name in policies]
    cols: dict[str, list] = {k: [] for k in ("frames", "episode", "speed", "members_rel", "members_px", "policy")}

    def grab(e, ep: int, k: int) -> None:
        rgb, seg = world.render_first_person(size, size, segmentation=True)
        rel, px = _member_pixels(world, cam, seg)
        obs = e.unwrapped.observe()
        for key, v in (("frames", rgb), ("episode", ep), ("speed", obs[VEL_FORWARD:VEL_LEFT + 1]), ("members_rel", rel),
                       ("members_px", px), ("policy", k)):
            cols[key].append(v)

    try:
        for ep in range(episodes):
            k = ep % len(built)
            run_episode(env, built[k], seed + ep, keep_trajectory=False,
                        on_step=lambda e, ep=ep, k=k: grab(e, ep, k))
            if progress:
                progress(1)
    finally:
        env.close()
    dtypes = {"frames": np.uint8, "episode": np.int32, "speed": np.float32, "members_rel": np.float32,
              "members_px": np.float32, "policy": np.int8}
    out = {k: np.asarray(v, dtype=dtypes[k]) for k, v in cols.items()}
    out["policies"] = np.asarray(policies)
    out["camera_hfov"] = np.float32(world.robot_params.camera_hfov_deg)
    return out


def save_frames(path: str | Path, data: dict[str, np.ndarray]) -> Path:
    """Write a frames file atomically (compressed: the renders are mostly flat colours)."""
    def writer(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **data)

    return atomic_write(path, writer)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of an .npz archive; anything else is one line saying what the file is instead."""
    def refuse(what: str) -> FramesError:
        return FramesError(f"--frames {path}: not a frames file written by tools/collect_frames.py (expected an "
                           f".npz archive of the arrays {sorted(KEYS)}; this is {what})")

    with open(path, "rb") as fh:
        head = fh.read(6)
    if not head.startswith(b"PK"):  # numpy reads a text file as pickled data and an .npy as one array
        raise refuse("a single .npy array" if head == b"\x93NUMPY" else "not an .npz (zip) archive")
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    except ValueError as exc:  # object arrays: pickled data, which a frames file never holds
        raise refuse("an archive of pickled (object) arrays") from exc
    except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise refuse("a damaged or cut-short .npz archive") from exc


def load_frames(path: str | Path, size: int | None = None) -> dict[str, np.ndarray]:
    """Read and check a frames file; ``size`` (the encoder's input) must match the frames' resolution."""
    path = Path(path)
    if not path.is_file():
        raise FramesError(f"--frames {path}: file not found (expected an .npz from tools/collect_frames.py)")
    data = _read_npz(path)
    missing = sorted(set(KEYS) - set(data))
    if missing:
        raise FramesError(f"--frames {path}: missing key(s) {missing}; expected {sorted(KEYS)} "
                          f"(tools/collect_frames.py)")
    for key, ndim in KEYS.items():
        if data[key].ndim != ndim:
            raise FramesError(f"--frames {path}: '{key}' has shape {data[key].shape}, expected {ndim} dimensions")
    f = data["frames"]
    n = len(f)
    if f.dtype != np.uint8 or f.shape[1] != f.shape[2] or f.shape[3] != 3 or n < 3:
        raise FramesError(f"--frames {path}: 'frames' is {f.shape} {f.dtype}; expected (N >= 3, S, S, 3) uint8")
    for key in ("episode", "speed", "members_rel", "members_px", "policy"):
        if len(data[key]) != n:
            raise FramesError(f"--frames {path}: '{key}' has {len(data[key])} rows, 'frames' has {n}")
    if size is not None and f.shape[1] != size:
        raise FramesError(f"--frames {path}: frames are {f.shape[1]}x{f.shape[2]}, the encoder takes "
                          f"{size}x{size} (collect frames with --size {size})")
    if "camera_hfov" in data and data["camera_hfov"].ndim != 0:
        raise FramesError(f"--frames {path}: 'camera_hfov' has shape {data['camera_hfov'].shape}, expected a scalar")
    return data


def check_hfov(deg: float | None, flag: str = "--camera-hfov") -> None:
    """A camera field of view a user asked for: None (Pepper's) or 5..120 degrees."""
    if deg is not None and not 5.0 <= deg <= 120.0:
        raise FramesError(f"{flag} {deg:g}: expected 5..120 degrees")


def frames_hfov(data: dict[str, np.ndarray]) -> float:
    """The field of view (degrees) the frames were seen through; Pepper's for files without the key."""
    return float(data["camera_hfov"]) if "camera_hfov" in data else RobotParams().camera_hfov_deg
