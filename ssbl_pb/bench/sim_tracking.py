"""The tracker on Pepper's first-person TinyRenderer frames, scored against the simulator's member positions.

The sim camera is ``perception.camera.PinholeCamera`` built from ``RobotParams`` (horizontal FOV 56.3 deg,
square pixels, TinyRenderer's principal point ``(w/2, h/2 - 1)``, see ``env.view.cameras``). A box becomes a
robot-frame ground position from its bottom edge (feet on the floor, pushed back by the legs' radius) or,
when the feet are below the image, from its top edge (head top at ``ProxyGeometry.head_top``, read from the
scene by ``proxy_geometry``). The robot drives towards
the group while weaving, so the tracker's ego-motion compensation is exercised.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..core.layouts import GroupModel
from ..env.view.bullet import pybullet as pb
from ..env.view.world import World
from ..errors import UserError
from ..params import RobotParams, WorldParams
from ..perception.camera import sim_camera
from ..perception.detection.detectors import ColourDetector, SimDetector
from ..perception.detection.ground import ProxyGeometry, boxes_to_ground
from ..perception.tracking.tracker import Tracker, TrackerParams
from ..urdf import HUMAN_COLOURS


def proxy_geometry(world: World) -> ProxyGeometry:
    """The proxy's heights as PyBullet renders them, read from member 0's link frames and visual shapes
    (so a change of URDF, or of how the world places bodies, is followed). Call after ``world.reset``."""
    hid, c = world.human_ids[0], world.client
    world.sync()
    joints = {pb.getJointInfo(hid, j, physicsClientId=c)[12].decode(): j
              for j in range(pb.getNumJoints(hid, physicsClientId=c))}
    vis = {(v[1], v[2]): v for v in pb.getVisualShapeData(hid, physicsClientId=c)}
    head, torso = joints["head"], joints["torso"]
    head_z = pb.getLinkState(hid, head, physicsClientId=c)[4][2]
    torso_z = pb.getLinkState(hid, torso, physicsClientId=c)[4][2]
    head_r = vis[(head, pb.GEOM_SPHERE)][3][0]
    box = vis[(torso, pb.GEOM_BOX)]
    mid, half = torso_z + box[5][2], box[3][2] / 2
    return ProxyGeometry(head_top=head_z + head_r, torso=(mid - half, mid + half))


@dataclasses.dataclass(frozen=True)
class SimEvalParams:
    """Simulation evaluation settings."""

    episodes: int = 4
    steps: int = 150  # control steps per episode (dt = 0.1 s)
    width: int = 320
    height: int = 240
    detector: str = "seg"  # "seg" (segmentation mask) or "colour" (RGB only)
    max_range: float = 4.0  # m, humans within this distance of the robot are scored
    match_dist: float = 1.0  # m, a track further than this from a member does not count as tracking it
    seed: int = 0


def _drive(world: World, t: float) -> np.ndarray:
    """Head for a point 1.6 m from the group centre, weaving sideways and in yaw."""
    x, y, yaw = world.robot_pose
    cx, cy = world.group.centre0
    dx, dy = cx - x, cy - y
    dist = math.hypot(dx, dy)
    bearing = math.atan2(dy, dx) - yaw
    bearing = math.atan2(math.sin(bearing), math.cos(bearing))
    fwd = 0.3 if dist > 1.8 else 0.0
    return np.array([fwd, 0.12 * math.sin(0.8 * t), 1.2 * bearing + 0.4 * math.sin(0.5 * t)])


def evaluate_sim(params: SimEvalParams | None = None, tracker: TrackerParams | None = None,
                 world_params: WorldParams | None = None,
                 custom: Callable[[World], np.ndarray] | None = None,
                 robot_params: RobotParams | None = None) -> dict[str, float]:
    """Run episodes; returns position-error statistics (m) of tracks against members within ``max_range``.

    ``custom(world) -> (n, 2)`` robot-frame detections replaces the named detector (``detector`` is then only
    its label; members are scored within the camera's field of view, as for ``colour``)."""
    p = params or SimEvalParams()
    if custom is None and p.detector not in ("seg", "colour"):
        raise UserError(f"detector = {p.detector!r}: expected 'seg' or 'colour'")
    rng = np.random.default_rng(p.seed)
    world = World(world_params, robot_params, groups=GroupModel("paper"))  # the groups its benchmarks used
    errors, visible, tracked = [], 0, 0
    try:
        cam = sim_camera(world.robot_params, p.width, p.height)
        seg_det = SimDetector(world.human_ids)
        col_det = ColourDetector(HUMAN_COLOURS)
        for _ in range(p.episodes):
            world.reset(rng, n_humans=int(rng.integers(2, 6)))
            geom = proxy_geometry(world)
            trk = Tracker(tracker or TrackerParams(dt=world.params.dt, meas_std=0.1, birth_hits=2))
            for k in range(p.steps):
                if custom is not None:
                    xy = custom(world)
                elif p.detector == "seg":
                    _, seg = world.render_first_person(p.width, p.height, segmentation=True)
                    boxes, members = seg_det.with_index(seg)
                    xy = boxes_to_ground(cam, boxes, geom)
                else:
                    rgb, _ = world.render_first_person(p.width, p.height)
                    boxes = col_det(rgb)
                    xy = boxes_to_ground(cam, boxes, geom, torso=True)
                xy = xy[~np.isnan(xy[:, 0])]
                states = trk.update(xy, odom=world.robot_pose.copy())
                # score: members within range and in the camera's view this frame
                pose = world.robot_pose
                c, s = math.cos(pose[2]), math.sin(pose[2])
                d = world.group.pos - pose[None, :2]
                local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
                in_view = np.zeros(len(local), dtype=bool)
                by_mask = custom is None and p.detector == "seg"  # in view = seen in the segmentation mask
                if by_mask:
                    in_view[members] = True
                rngs = np.hypot(local[:, 0], local[:, 1])
                for i in np.flatnonzero((rngs <= p.max_range) & (in_view | (not by_mask))):
                    if not by_mask and abs(math.atan2(local[i, 1], local[i, 0])) > math.radians(
                            world.robot_params.camera_hfov_deg / 2):
                        continue
                    visible += 1
                    if not states:
                        continue
                    dd = [float(np.hypot(*(st.position - local[i]))) for st in states]
                    j = int(np.argmin(dd))
                    if dd[j] <= p.match_dist:
                        tracked += 1
                        errors.append(dd[j])
                world.step(_drive(world, k * world.params.dt))
    finally:
        world.close()
    e = np.array(errors)
    return {"median_err_m": float(np.median(e)) if len(e) else float("nan"),
            "p90_err_m": float(np.percentile(e, 90)) if len(e) else float("nan"),
            "coverage": tracked / visible if visible else float("nan"), "scored": int(len(e)),
            "visible": int(visible), "episodes": p.episodes, "steps": p.steps, "width": p.width,
            "height": p.height, "detector": p.detector, "max_range_m": p.max_range,
            "proxy_head_top_m": geom.head_top, "proxy_torso_m": list(geom.torso)}
