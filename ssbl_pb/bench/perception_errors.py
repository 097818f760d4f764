"""Perception's errors where they arise: deploy's log (``DIR/log.jsonl``: what perception made of the camera, in
the odometry frame) held against the virtual Pepper's ground truth (its ``--log``: room frame), tick by tick.

Each deploy tick is matched to the virtual Pepper state nearest in wall time (the tick's ``now``: its row's
``wall`` less the time from reading odometry to sending the command). The truth is moved into the odometry frame
(its origin is the robot's start pose in the room frame, ``robot.relative``). Tracks are assigned to members by
the Hungarian method on distance within ``gate_m``; a track left over within ``gate_m`` of a member is a
*duplicate* of its nearest member, one farther from every member a *false* track. A member with no track is
*missed*, one with no track detected in this frame (``seen``) *unseen*; both are split by why, from the true
geometry at the camera (``view_class``): out of view (its centre outside the camera's horizontal field of view),
at the edge (its centre in view, its body's side not: deploy drops boxes cut by the image's side), occluded (the
line of sight to its centre passes within a body's half-width of a nearer member) or in view (not detected).

What a run yields (``analyse``) is kept as samples, so runs pool (``pool``) before ``summarise`` turns them into
the numbers the benchmark reports and ``perception_errors_plot.plot`` into its figure. The policy's sensitivity
to all of it is the difference between its network's deterministic actions on the perceived and on the true
observation of the same tick (``observations``: both built as ``DeployLoop._act`` builds one, with
``observation.vector_observation``; the walls and scan of deploy's own frames for both, so only perception
differs; no action filter, no shield).
"""

from __future__ import annotations

import bisect
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..agents.trained import DEFAULT_VIEW, PolicyView
from ..core import observation as ob
from ..core.layouts import member_keep_out
from ..core.task import TaskParams
from ..deploy.frames import Frames, inverse, load_room, transform_points
from ..deploy.log import RUN, read_log
from ..deploy.robot import compose
from ..params import RobotParams, SocialParams
from ..perception.camera import sim_camera
from ..perception.groups.estimate import BODY_HEIGHT, KEYPOINT_GROUP, TORSO_HALF
from ..perception.groups.observation_model import IMAGE_SIZE, PerceptionParams, hidden_share, image_share
from ..virtual.pepper import load_log

VIEW_CLASSES = ("in_view", "edge", "occluded", "out_of_view")  # why a member may be missed, by the true geometry
DISTANCE_BINS = (0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 6.0, math.inf)  # m, for position error against distance
BEARING_BINS = (0.0, 10.0, 20.0, 28.0, 40.0, 60.0, 90.0, 180.0)  # deg |bearing|, for miss rates
MEMBER_VELOCITY = [14 + ob.MEMBER_FIELDS * k + j for k in range(ob.MAX_MEMBERS) for j in (2, 3)]  # observation


@dataclasses.dataclass(frozen=True)
class ErrorParams:
    """How tracks are judged against the truth."""

    gate_m: float = 0.75  # a track this close to a member may be its track (members stand 0.6-1.2 m apart)
    hfov_deg: float = RobotParams.camera_hfov_deg  # the camera's horizontal field of view
    camera_forward: float = RobotParams.camera_forward  # m the camera sits ahead of the base's centre
    body_halfwidth_m: float = 0.23  # the torso's half-width (urdf/human.urdf; what the colour detector sees)
    max_gap_s: float = 0.1  # a deploy tick with no virtual Pepper state this close in wall time is skipped
    edge_margin_m: float = KEYPOINT_GROUP.edge_margin_m  # m beyond the torso that must be in the image too for
    #   ``Samples.in_image`` to count it whole (MoveNet's chain, ``PerceptionParams.min_visible``; colour's: 0)


@dataclasses.dataclass
class Samples:
    """What one or more runs yield. Per member and tick: ``range_m``, ``bearing_deg`` (from the robot's centre,
    left positive), ``view`` (index in ``VIEW_CLASSES``), ``tracks`` (how many tracks are on it: 0 missed, 2+
    duplicated), ``seen`` (one of them detected in this frame), ``pos_err``/``vel_err`` (m, m/s, of its assigned
    track; NaN when missed) and ``remembered`` (its assigned track is not seen). Per tick: ``false_tracks``. Per
    policy tick: group errors (m) and the action difference (perceived - true network action; ``_still``: with the
    members' velocity entries zeroed in both, what positions and the group estimate alone move). ``ids``: per run
    and true member, the track ids on it over the run, in order of first appearance."""

    range_m: list[float] = dataclasses.field(default_factory=list)
    bearing_deg: list[float] = dataclasses.field(default_factory=list)
    view: list[int] = dataclasses.field(default_factory=list)
    tracks: list[int] = dataclasses.field(default_factory=list)
    seen: list[bool] = dataclasses.field(default_factory=list)
    pos_err: list[float] = dataclasses.field(default_factory=list)
    vel_err: list[float] = dataclasses.field(default_factory=list)
    remembered: list[bool] = dataclasses.field(default_factory=list)
    false_tracks: list[int] = dataclasses.field(default_factory=list)
    centre_err: list[float] = dataclasses.field(default_factory=list)
    radius_err: list[float] = dataclasses.field(default_factory=list)
    slot_err: list[float] = dataclasses.field(default_factory=list)
    action_delta: list[list[float]] = dataclasses.field(default_factory=list)
    action_delta_still: list[list[float]] = dataclasses.field(default_factory=list)  # members' velocities zeroed
    ids: list[list[list[int]]] = dataclasses.field(default_factory=list)
    switches: list[int] = dataclasses.field(default_factory=list)  # per run: changes of a member's assigned id
    shared_ids: list[int] = dataclasses.field(default_factory=list)  # per run: ids assigned to 2+ members
    # per member-tick, for the observation model (``bench.observation_fit``): its assigned track's range (m) and
    # bearing (deg) error, facing error (deg; NaN: no facing), whether its front is toward the robot (within
    # ``PerceptionParams().facing_front_deg``), and the shares of its torso hidden behind nearer members and inside
    # the image (``observation_model.hidden_share``, ``image_share``)
    range_err: list[float] = dataclasses.field(default_factory=list)
    bearing_err: list[float] = dataclasses.field(default_factory=list)
    facing_err: list[float] = dataclasses.field(default_factory=list)
    front: list[bool] = dataclasses.field(default_factory=list)
    hidden: list[float] = dataclasses.field(default_factory=list)
    in_image: list[float] = dataclasses.field(default_factory=list)


def pool(parts: list[Samples]) -> Samples:
    """The samples of several runs as one."""
    out = Samples()
    for part in parts:
        for f in dataclasses.fields(Samples):
            getattr(out, f.name).extend(getattr(part, f.name))
    return out


# -- frames and matching ---------------------------------------------------------------------------------------
def room_to_odom(start_pose: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Room-frame points (n, 2) in the odometry frame, whose origin is the robot's start pose in the room."""
    return transform_points(inverse(np.asarray(start_pose, dtype=float)), xy)


def rotate(yaw: float, v: np.ndarray) -> np.ndarray:
    """Vectors (n, 2) turned by ``yaw`` (rad)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.asarray(v, dtype=float).reshape(-1, 2) @ np.array([[c, s], [-s, c]])


def tick_wall(row: dict[str, Any]) -> float:
    """Wall time of a deploy tick's ``now`` (odometry read, people extrapolated to it): the row is written after
    the command was sent, ``tick_ms - odom_ms`` later."""
    return float(row["wall"]) - 1e-3 * max(0.0, float(row.get("tick_ms") or 0.0) - float(row.get("odom_ms") or 0.0))


def match_ticks(rows: list[dict[str, Any]], states: list[dict[str, Any]], max_gap_s: float = 0.1
                ) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(deploy row, virtual Pepper state) pairs: each row with the state nearest its ``tick_wall``."""
    states = sorted(states, key=lambda s: s["wall"])
    walls = [float(s["wall"]) for s in states]
    out = []
    for row in rows:
        t = tick_wall(row)
        k = bisect.bisect_left(walls, t)
        near = [i for i in (k - 1, k) if 0 <= i < len(walls)]
        if not near:
            continue
        i = min(near, key=lambda i: abs(walls[i] - t))
        if abs(walls[i] - t) <= max_gap_s:
            out.append((row, states[i]))
    return out


def view_class(robot_pose: np.ndarray, members: np.ndarray, p: ErrorParams | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Range (m) and bearing (deg, left positive) from the robot's centre, and the ``VIEW_CLASSES`` index (judged
    from the camera) of each member (n, 2), all in the frame of ``robot_pose`` (x, y, yaw). Out of view wins over
    occluded, occluded over the edge."""
    p = p or ErrorParams()
    pts = np.asarray(members, dtype=float).reshape(-1, 2)
    x, y, yaw = (float(v) for v in robot_pose[:3])
    body = rotate(-yaw, pts - np.array([x, y]))  # robot frame: x ahead, y left
    d = body - np.array([p.camera_forward, 0.0])  # from the camera
    rng = np.hypot(d[:, 0], d[:, 1])
    bearing = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    half = 0.5 * p.hfov_deg
    side = np.degrees(np.arctan2(p.body_halfwidth_m, np.maximum(rng, 1e-6)))
    cls = np.where(np.abs(bearing) > half, 3, np.where(np.abs(bearing) + side > half, 1, 0))
    for i in range(len(pts)):
        if cls[i] == 3:
            continue
        u = d[i] / max(rng[i], 1e-9)
        for j in range(len(pts)):
            along = float(d[j] @ u)
            if j != i and 0 < along < rng[i] and abs(float(d[j, 0] * u[1] - d[j, 1] * u[0])) < p.body_halfwidth_m:
                cls[i] = 2
    return np.hypot(body[:, 0], body[:, 1]), np.degrees(np.arctan2(body[:, 1], body[:, 0])), cls


def assign(tracks: np.ndarray, members: np.ndarray, gate_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Tracks (k, 2) to members (n, 2): ``primary`` (n,) the track assigned to each member (-1: none; Hungarian
    on distance within ``gate_m``) and ``owner`` (k,) the member each track is on (-1: a false track): its
    assigned member, or the nearest member within ``gate_m`` for a track left over (a duplicate)."""
    tracks = np.asarray(tracks, dtype=float).reshape(-1, 2)
    members = np.asarray(members, dtype=float).reshape(-1, 2)
    primary, owner = np.full(len(members), -1), np.full(len(tracks), -1)
    if not len(tracks) or not len(members):
        return primary, owner
    dist = np.hypot(*(tracks[:, None, :] - members[None, :, :]).transpose(2, 0, 1))  # (k, n)
    rows, cols = linear_sum_assignment(np.where(dist <= gate_m, dist, 1e9))
    for r, c in zip(rows, cols, strict=True):
        if dist[r, c] <= gate_m:
            primary[c], owner[r] = r, c
    for r in np.flatnonzero(owner < 0):
        c = int(np.argmin(dist[r]))
        if dist[r, c] <= gate_m:
            owner[r] = c
    return primary, owner


# -- observations -----------------------------------------------------------------------------------------------
def deploy_frames(deploy_dir: Path, rows: list[dict[str, Any]]) -> Frames:
    """Deploy's frames as it ran (its ``--map`` and start pose from ``run.json``), anchored at its first tick."""
    info = json.loads((Path(deploy_dir) / RUN).read_text()) if (Path(deploy_dir) / RUN).is_file() else {}
    room = load_room(info["map"]) if info.get("map") else None
    start = info.get("start_pose_map")
    fr = Frames(room, None if start is None else np.asarray(start, dtype=float))
    fr.room_from_odom = room_from_odom(rows[0]) if rows else np.zeros(3)
    return fr


def room_from_odom(row: dict[str, Any]) -> np.ndarray:
    """The pose of the odometry frame in deploy's room frame, from a tick row."""
    odom = np.array([row["odom_x"], row["odom_y"], row["odom_yaw"]], dtype=float)
    return compose(np.asarray(row["room_pose"], dtype=float), inverse(odom))


def observation(fr: Frames, odom_pose: np.ndarray, body_vel: np.ndarray, members: np.ndarray, member_vel: np.ndarray,
                centre: np.ndarray, radius: float, slot: np.ndarray, robot: RobotParams,
                view: PolicyView = DEFAULT_VIEW, reach_margin: float = 0.0) -> np.ndarray:
    """The Vector observation from odometry-frame inputs, as ``DeployLoop._act`` builds it for a policy that sees
    as ``view`` tells."""
    room = fr.room_pose(np.asarray(odom_pose, dtype=float))
    rot = float(fr.room_from_odom[2])
    mvel_room = rotate(rot, member_vel)
    v = np.asarray(body_vel, dtype=float)
    cy, sy = math.cos(room[2]), math.sin(room[2])
    vel_room = np.array([cy * v[0] - sy * v[1], sy * v[0] + cy * v[1], v[2]])
    centre_room, slot_room = fr.room_points(np.array([centre, slot], dtype=float))
    members_room = fr.room_points(np.asarray(members, dtype=float).reshape(-1, 2))
    if view.waypoints:
        slot_room = fr.way_to(room, members_room, centre_room, slot_room, robot.reach, reach_margin,
                              view.waypoints_near_group)
    frame = ob.approach_yaw(room, centre_room)
    return ob.vector_observation(room, vel_room, members_room, mvel_room, centre_room, radius, slot_room,
                                 fr.walls(room), robot.max_speed, robot.max_yaw_rate, frame, fr.scan(room, frame),
                                 view.member_order)


def network_actions(policy: Any, obs: np.ndarray) -> np.ndarray:
    """The policy network's deterministic actions (n, k) for observations (n, d): a trained model's
    normalisation and network only (no action filter, no shield, a recurrent one from a fresh state); any other
    policy through its ``predict``, reset before each."""
    obs = np.asarray(obs, dtype=np.float32).reshape(len(obs), -1)
    if hasattr(policy, "model") and hasattr(policy, "normalize"):
        x = obs[:, :ob.BASE_SIZE] if getattr(policy, "base_only", False) else obs
        x = policy.normalize(x)
        if getattr(policy, "recurrent", False):
            start = np.ones(len(x), dtype=bool)
            return np.asarray(policy.model.predict(x, state=None, episode_start=start, deterministic=True)[0])
        return np.asarray(policy.model.predict(x, deterministic=True)[0]).reshape(len(x), -1)
    out = []
    for o in obs:
        if hasattr(policy, "reset"):
            policy.reset()
        out.append(np.ravel(policy.predict(o, state=None, episode_start=np.ones(1, dtype=bool),
                                           deterministic=True)[0]))
    return np.array(out).reshape(len(obs), -1)


# -- one run ----------------------------------------------------------------------------------------------------
def analyse(rows: list[dict[str, Any]], start: dict[str, Any], states: list[dict[str, Any]],
            p: ErrorParams | None = None, policy: Any = None, frames: Frames | None = None,
            robot: RobotParams | None = None, view: PolicyView = DEFAULT_VIEW, reach_margin: float = 0.0) -> Samples:
    """The samples of one run from deploy's tick rows and the virtual Pepper's start row and states. With a
    ``policy``, also its network's action difference on every policy tick (``frames``: deploy's, default no map;
    ``view``: how the policy's observation is made, ``reach_margin`` the body reach ``way_to`` keeps)."""
    p = p or ErrorParams()
    robot = robot or RobotParams()
    s = Samples()
    start_pose = np.asarray(start["start_pose"], dtype=float)
    ids: dict[int, list[int]] = {}
    last: dict[int, int] = {}
    owners: dict[int, set[int]] = {}
    switches = 0
    perceived, true = [], []
    camera = sim_camera(robot, *IMAGE_SIZE)
    fr_p = fr_t = None
    if policy is not None and rows:
        fr_p = frames or Frames()
        if fr_p.room_from_odom is None:
            fr_p.room_from_odom = room_from_odom(rows[0])
        fr_t = _copy_frames(fr_p)  # its own plan cache (``way_to``)
    for row, st in match_ticks(rows, states, p.max_gap_s):
        pose = np.asarray(st["odom"], dtype=float)
        members = room_to_odom(start_pose, np.asarray(st["members"], dtype=float))
        mvel = rotate(-float(start_pose[2]), np.asarray(st.get("member_vel") or np.zeros_like(members)))
        rng, bearing, cls = view_class(pose, members, p)
        humans = row.get("humans") or []
        txy = np.array([[h["x"], h["y"]] for h in humans], dtype=float).reshape(-1, 2)
        tvel = np.array([[h.get("vx", 0.0), h.get("vy", 0.0)] for h in humans], dtype=float).reshape(-1, 2)
        tseen = np.array([bool(h.get("seen", True)) for h in humans], dtype=bool)
        primary, owner = assign(txy, members, p.gate_m)
        s.false_tracks.append(int((owner < 0).sum()))
        _model_samples(s, pose, members, np.vstack([txy, [0.0, 0.0]])[primary], primary >= 0, camera, p, [
            humans[k].get("facing") if k >= 0 else None for k in primary],
            np.asarray(st.get("member_yaw") or np.full(len(members), np.nan), dtype=float) - start_pose[2])
        for j in range(len(members)):
            on = np.flatnonzero(owner == j)
            k = int(primary[j])
            s.range_m.append(float(rng[j]))
            s.bearing_deg.append(float(bearing[j]))
            s.view.append(int(cls[j]))
            s.tracks.append(len(on))
            s.seen.append(bool(tseen[on].any()) if len(on) else False)
            s.pos_err.append(float(np.hypot(*(txy[k] - members[j]))) if k >= 0 else math.nan)
            s.vel_err.append(float(np.hypot(*(tvel[k] - mvel[j]))) if k >= 0 else math.nan)
            s.remembered.append(bool(k >= 0 and not tseen[k]))
            for r in on:
                tid = int(humans[r]["id"])
                seq = ids.setdefault(j, [])
                if tid not in seq:
                    seq.append(tid)
                owners.setdefault(tid, set()).add(j)
            if k >= 0:
                tid = int(humans[k]["id"])
                switches += j in last and last[j] != tid
                last[j] = tid
        if row.get("centre") is not None:
            centre = room_to_odom(start_pose, np.asarray(st["centre"], dtype=float))[0]
            slot = room_to_odom(start_pose, np.asarray(st["slot"], dtype=float))[0]
            s.centre_err.append(float(np.hypot(*(np.asarray(row["centre"]) - centre))))
            s.slot_err.append(float(np.hypot(*(np.asarray(row["slot"]) - slot))))
            if st.get("radius") is not None and row.get("radius") is not None:
                s.radius_err.append(float(row["radius"]) - float(st["radius"]))
            if policy is not None:
                args = (robot, view, reach_margin)
                opose = np.array([row["odom_x"], row["odom_y"], row["odom_yaw"]], dtype=float)
                perceived.append(observation(fr_p, opose, np.asarray(row["vel"]), txy, tvel, np.asarray(row["centre"]),
                                             float(row["radius"]), np.asarray(row["slot"]), *args))
                true.append(observation(fr_t, pose, np.asarray(st["vel"]), members, mvel, centre,
                                        float(st.get("radius", row["radius"])), slot, *args))
    if perceived:
        obs_p, obs_t = np.array(perceived), np.array(true)
        s.action_delta.extend((network_actions(policy, obs_p) - network_actions(policy, obs_t)).tolist())
        obs_p[:, MEMBER_VELOCITY] = obs_t[:, MEMBER_VELOCITY] = 0.0
        s.action_delta_still.extend((network_actions(policy, obs_p) - network_actions(policy, obs_t)).tolist())
    s.ids.append([ids.get(j, []) for j in range(max(ids, default=-1) + 1)])
    s.switches.append(switches)
    s.shared_ids.append(sum(len(v) > 1 for v in owners.values()))
    return s


def _model_samples(s: Samples, pose: np.ndarray, members: np.ndarray, tracks: np.ndarray, assigned: np.ndarray,
                   camera: Any, p: ErrorParams, facing: list[float | None], yaw: np.ndarray) -> None:
    """``Samples``' per member-tick fields for the observation model (odometry frame; ``tracks`` (n, 2) the
    assigned tracks where ``assigned``, ``facing`` theirs (rad or None), ``yaw`` the members' true yaws)."""
    x, y, th = (float(v) for v in pose[:3])
    body, seen_at = rotate(-th, members - [x, y]), rotate(-th, tracks - [x, y])
    r_true, r_seen = np.hypot(*body.T), np.hypot(*seen_at.T)
    b_err = np.remainder(np.arctan2(seen_at[:, 1], seen_at[:, 0]) - np.arctan2(body[:, 1], body[:, 0]) + math.pi,
                         2 * math.pi) - math.pi
    f = np.array([np.nan if v is None else float(v) for v in facing])
    toward = np.arctan2(y - members[:, 1], x - members[:, 0])  # from each member to the robot
    s.range_err.extend(np.where(assigned, r_seen - r_true, np.nan).tolist())
    s.bearing_err.extend(np.where(assigned, np.degrees(b_err), np.nan).tolist())
    s.facing_err.extend(np.degrees(np.remainder(f - yaw + math.pi, 2 * math.pi) - math.pi).tolist())
    s.front.extend((np.abs(np.remainder(yaw - toward + math.pi, 2 * math.pi) - math.pi)
                    <= math.radians(PerceptionParams().facing_front_deg)).tolist())
    s.hidden.extend(hidden_share(body, TORSO_HALF[1]).tolist())
    half = 2.0 * sum(TORSO_HALF) / math.pi + p.edge_margin_m  # the torso's mean over facings, as the model's
    s.in_image.extend(image_share(body, camera, half, BODY_HEIGHT, math.inf).tolist())


def _copy_frames(fr: Frames) -> Frames:
    out = Frames(fr.room, fr.start_map)
    out.room_from_odom = fr.room_from_odom
    return out


def analyse_folder(folder: Path, policy: Any = None, p: ErrorParams | None = None,
                   view: PolicyView = DEFAULT_VIEW) -> Samples:
    """``analyse`` of a benchmark run's folder (``deploy/`` and ``virtual_pepper.jsonl``, as ``bench`` writes)."""
    folder = Path(folder)
    rows = read_log(folder / "deploy")
    start, states, _ = load_log(folder / "virtual_pepper.jsonl")
    info = json.loads((folder / "deploy" / RUN).read_text()) if (folder / "deploy" / RUN).is_file() else {}
    robot = RobotParams(**info["robot"]) if isinstance(info.get("robot"), dict) else RobotParams()
    margin = member_keep_out(SocialParams(), robot.reach, TaskParams().intimate_zone)  # as deploy's way_to is given
    frames = deploy_frames(folder / "deploy", rows) if policy is not None else None
    return analyse(rows, start, states, p, policy, frames, robot, view, margin)


# -- summaries --------------------------------------------------------------------------------------------------
def _stats(x: Any) -> dict[str, float | int | None]:
    a = np.asarray(x, dtype=float)
    a = a[np.isfinite(a)]
    if not len(a):
        return {"n": 0, "median": None, "mean": None, "p90": None}
    return {"n": int(len(a)), "median": float(np.median(a)), "mean": float(a.mean()),
            "p90": float(np.percentile(a, 90))}


def binned(x: Any, y: Any, edges: tuple[float, ...]) -> list[dict[str, Any]]:
    """``_stats`` of ``y`` in bins of ``x`` (``edges``, lower edge inclusive)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (x >= lo) & (x < hi)
        out.append({"lo": lo, "hi": None if math.isinf(hi) else hi, **_stats(y[inside])})
    return out


def summarise(s: Samples) -> dict[str, Any]:
    """The numbers the benchmark reports (JSON-ready)."""
    view = np.asarray(s.view, dtype=int)
    tracks = np.asarray(s.tracks, dtype=int)
    seen = np.asarray(s.seen, dtype=bool)
    remembered = np.asarray(s.remembered, dtype=bool)
    pos, vel = np.asarray(s.pos_err, dtype=float), np.asarray(s.vel_err, dtype=float)
    rng, bearing = np.asarray(s.range_m, dtype=float), np.abs(np.asarray(s.bearing_deg, dtype=float))
    n = len(view)
    missed, unseen = tracks == 0, ~seen
    by_view = {}
    for k, name in enumerate(VIEW_CLASSES):
        here = view == k
        by_view[name] = {"member_ticks": int(here.sum()), "missed": int((missed & here).sum()),
                         "unseen": int((unseen & here).sum()),
                         "missed_rate": float((missed & here).sum() / here.sum()) if here.any() else None,
                         "unseen_rate": float((unseen & here).sum() / here.sum()) if here.any() else None}
    ids = [len(seq) for run in s.ids for seq in run]
    detected = seen & ~remembered  # the assigned track itself was detected in this frame
    bins_bearing = []
    for lo, hi in zip(BEARING_BINS[:-1], BEARING_BINS[1:], strict=True):
        here = (bearing >= lo) & (bearing < hi)
        bins_bearing.append({"lo": lo, "hi": hi, "n": int(here.sum()),
                             "missed_rate": float(missed[here].mean()) if here.any() else None,
                             "unseen_rate": float(unseen[here].mean()) if here.any() else None})
    def actions(delta: list[list[float]]) -> dict[str, Any]:
        d = np.asarray(delta, dtype=float).reshape(len(delta), -1) if delta else np.zeros((0, 2))
        return {"ticks": len(d), "mean_abs": np.abs(d).mean(axis=0).tolist() if len(d) else None,
                **{k: v for k, v in _stats(np.hypot(*d[:, :2].T) if len(d) else []).items() if k != "n"}}

    return {
        "member_ticks": n, "ticks": len(s.false_tracks),
        "position_error_m": {"seen": _stats(pos[detected]), "remembered": _stats(pos[remembered])},
        "position_error_by_distance": binned(rng[detected], pos[detected], DISTANCE_BINS),
        "remembered_error_by_distance": binned(rng[remembered], pos[remembered], DISTANCE_BINS),
        "velocity_error_mps": {"seen": _stats(vel[detected]), "remembered": _stats(vel[remembered])},
        "missed": {"count": int(missed.sum()), "rate": float(missed.mean()) if n else None, **{
            name: by_view[name]["missed"] for name in VIEW_CLASSES}},
        "unseen": {"count": int(unseen.sum()), "rate": float(unseen.mean()) if n else None, **{
            name: by_view[name]["unseen"] for name in VIEW_CLASSES}},
        "by_view": by_view, "by_bearing": bins_bearing,
        "duplicated_member_ticks": int((tracks > 1).sum()), "duplicate_tracks": int(np.maximum(tracks - 1, 0).sum()),
        "false_tracks": int(sum(s.false_tracks)),
        "ids_per_member": {"mean": float(np.mean(ids)) if ids else None, "max": max(ids, default=None),
                           "members": len(ids), "new_ids": int(sum(max(k - 1, 0) for k in ids))},
        "id_switches": int(sum(s.switches)), "ids_on_several_members": int(sum(s.shared_ids)),
        "centre_error_m": _stats(s.centre_err), "slot_error_m": _stats(s.slot_err),
        "radius_error_m": {**_stats(np.abs(s.radius_err)), "bias": float(np.mean(s.radius_err)) if s.radius_err
                           else None},
        "action_delta": actions(s.action_delta), "action_delta_still": actions(s.action_delta_still),
    }


def markdown_table(runs: list[dict[str, Any]], total: dict[str, Any]) -> str:
    """A short table: per run and pooled, the errors that matter most."""
    def f(v: Any, fmt: str = ".2f") -> str:
        return "-" if v is None else format(v, fmt)

    head = ("| run | pos. error seen, median / p90 (m) | remembered (m) | vel. error (m/s) | missed: out of view / "
            "edge / occluded / in view | duplicated member-ticks | ids per member (max) | centre / slot error (m) | "
            "radius error (m) | mean \\|delta action\\| (members' velocities zeroed) |")
    out = [head, "|---" * 10 + "|"]
    each = [(str(r.get("seed", i)), r["perception"]) for i, r in enumerate(runs) if r.get("perception")]
    for name, r in [*each, ("all", total)]:
        m = r["missed"]
        ids = r["ids_per_member"]
        act = r["action_delta"]
        out.append(
            f"| {name} | {f(r['position_error_m']['seen']['median'])} / {f(r['position_error_m']['seen']['p90'])} | "
            f"{f(r['position_error_m']['remembered']['median'])} | {f(r['velocity_error_mps']['seen']['median'])} | "
            f"{m['out_of_view']} / {m['edge']} / {m['occluded']} / {m['in_view']} of {r['member_ticks']} | "
            f"{r['duplicated_member_ticks']} | {f(ids['mean'])} ({ids['max']}) | "
            f"{f(r['centre_error_m']['median'])} / {f(r['slot_error_m']['median'])} | "
            f"{f(r['radius_error_m']['median'])} | {f(act['mean'], '.3f')} "
            f"({f(r['action_delta_still']['mean'], '.3f')}) |")
    return "\n".join(out) + "\n"
