"""The Vector observation (paper III-B "Vector" mode): one layout shared by the simulator and the robot.

Everything is relative to the robot and expressed in the *approach frame*: x from the robot toward the group
centre, y to its left. The robot turns to face the centre (as in the original, where it always faces it), so
this is its body frame once it has turned; actions use the same frame, so a turning robot's commands do not
swing around with it. (With ``TaskParams.turn`` the policy steers and the frame is the body frame.) The same
vector is built from the simulator's state or from the tracker's output on the real robot.
Layout (``OBS_SIZE`` = 64; 40 without the range scan):

====  =========================================================  =========
idx   value                                                      scale
====  =========================================================  =========
0-1   free slot position (with ``waypoints``, in a room with     / 5 m
      obstacles, the way around them while the slot is out of
      sight: ``planner``)
2-3   conversation centre position                               / 5 m
4     o-space radius                                             / 5 m
5-6   robot velocity (forward, left)                             / max speed
7     robot turn rate                                            / max turn rate
8-9   the frame's orientation in the room (cos, sin)             1
10-13 distance to the walls (+x, -x, +y, -y, room frame)         / 5 m
14-38 up to 5 members in ``member_order``: position (2),       / 5 m, / 1 m/s
      velocity (2), present flag (1); absent members are zeros
39    robot heading minus the frame's (how far it still turns)   / pi
40-63 range scan: 24 sectors of 15 deg over 360 deg, sector k    / 3 m
      centred 15 k deg from the frame's x (toward the group
      centre): the nearest wall or obstacle within it, from the
      robot's centre (``obstacles.ray_range``)
====  =========================================================  =========

The original divides by half its 20 m arena (ref "Vector observation"); our default room is 10 m, so 5 m.
The scan (ours): each sector reports the nearest obstacle anywhere in it (a single ray per 15 deg
slipped past a map's 5 cm speckle); 3 m is the range naoqi_driver gives Pepper's lasers and 9 s of driving at the
default speed. Members are not in it (they have their own fields).

Member order (ours; the paper does not say): ``nearest`` first (the shipped policy) or by ``bearing`` from the
robot, leftmost first. In front of the gap between two members about equally far (the place across a group), the
nearest block swaps sides with a few centimetres of motion, and a policy reading it swings (docs/benchmarks_movenet.md,
"The nearest member's side"); their bearings stay apart there.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .base import wrap_angle

MAX_MEMBERS = 5
MEMBER_FIELDS = 5
# the layout's entries by name (the table above): the one place every reader (the env, the shield, the baselines,
# the camera wrappers, frame collection) takes them from
SLOT_X, SLOT_Y = 0, 1
CENTRE_X, CENTRE_Y = 2, 3
OSPACE_RADIUS = 4
VEL_FORWARD, VEL_LEFT, TURN_RATE = 5, 6, 7
FRAME_COS, FRAME_SIN = 8, 9
WALLS = 10  # four entries: +x, -x, +y, -y
MEMBERS = 14  # MAX_MEMBERS blocks of MEMBER_FIELDS, in ``MEMBER_ORDERS``
MEMBER_ORDERS = ("nearest", "bearing")  # nearest first; by bearing from the robot, leftmost first
MEMBER_X, MEMBER_Y, MEMBER_VX, MEMBER_VY, MEMBER_PRESENT = range(MEMBER_FIELDS)  # offsets within a block
HEADING = MEMBERS + MAX_MEMBERS * MEMBER_FIELDS
BASE_SIZE = HEADING + 1
SCAN_RAYS = 24
SCAN_RANGE = 3.0  # m
OBS_SIZE = BASE_SIZE + SCAN_RAYS
POS_SCALE = 5.0
OBS_LIMIT = 10.0


@njit(cache=True)
def fill_observation(o: np.ndarray, x: float, y: float, yaw: float, vx: float, vy: float, wz: float,
                     members_pos: np.ndarray, members_vel: np.ndarray, cx: float, cy: float, radius: float,
                     sx: float, sy: float, walls: tuple[float, float, float, float], max_speed: float,
                     max_yaw_rate: float, frame_yaw: float, by_bearing: bool = False) -> None:
    """Write the observation (the table above, up to index 39; any further entries become 0) into ``o``: the robot
    at (x, y, yaw) with world-frame velocity (vx, vy, wz), the members (k, 2) in world metres, centre (cx, cy), slot
    (sx, sy), the distances to the walls, in the frame turned by ``frame_yaw``; members nearest first, or with
    ``by_bearing`` leftmost first as seen in that frame (ties in index order either way)."""
    c, s = math.cos(frame_yaw), math.sin(frame_yaw)
    o[:] = 0.0
    o[SLOT_X], o[SLOT_Y] = (c * (sx - x) + s * (sy - y)) / POS_SCALE, (c * (sy - y) - s * (sx - x)) / POS_SCALE
    o[CENTRE_X], o[CENTRE_Y] = (c * (cx - x) + s * (cy - y)) / POS_SCALE, (c * (cy - y) - s * (cx - x)) / POS_SCALE
    o[OSPACE_RADIUS] = radius / POS_SCALE
    o[VEL_FORWARD], o[VEL_LEFT] = (c * vx + s * vy) / max_speed, (c * vy - s * vx) / max_speed
    o[TURN_RATE] = wz / max_yaw_rate
    o[FRAME_COS], o[FRAME_SIN] = c, s
    for w in range(4):
        o[WALLS + w] = walls[w] / POS_SCALE
    k = members_pos.shape[0]
    d2 = np.empty(k)
    for j in range(k):
        d2[j] = (members_pos[j, 0] - x) ** 2 + (members_pos[j, 1] - y) ** 2
    order = np.argsort(d2, kind="mergesort")[:MAX_MEMBERS]  # the nearest MAX_MEMBERS, ties in index order
    if by_bearing:
        left = np.empty(order.shape[0])
        for r in range(order.shape[0]):
            dx, dy = members_pos[order[r], 0] - x, members_pos[order[r], 1] - y
            left[r] = -math.atan2(dx * -s + dy * c, dx * c + dy * s)
        order = order[np.argsort(left, kind="mergesort")]
    for r in range(order.shape[0]):
        j = order[r]
        dx, dy = members_pos[j, 0] - x, members_pos[j, 1] - y
        b = MEMBERS + MEMBER_FIELDS * r
        o[b + MEMBER_X] = (dx * c + dy * s) * (1.0 / POS_SCALE)
        o[b + MEMBER_Y] = (dx * -s + dy * c) * (1.0 / POS_SCALE)
        o[b + MEMBER_VX] = members_vel[j, 0] * c + members_vel[j, 1] * s
        o[b + MEMBER_VY] = members_vel[j, 0] * -s + members_vel[j, 1] * c
        o[b + MEMBER_PRESENT] = 1.0
    o[HEADING] = wrap_angle(yaw - frame_yaw) / math.pi
    for t in range(o.shape[0]):
        o[t] = min(max(o[t], -OBS_LIMIT), OBS_LIMIT)


def vector_observation(
    robot_pose: np.ndarray,
    robot_vel: np.ndarray,
    members_pos: np.ndarray,
    members_vel: np.ndarray,
    centre: np.ndarray,
    radius: float,
    slot: np.ndarray,
    walls: np.ndarray,
    max_speed: float,
    max_yaw_rate: float,
    frame_yaw: float | None = None,
    scan: np.ndarray | None = None,
    member_order: str = "nearest",
) -> np.ndarray:
    """``fill_observation`` from arrays (world-frame metres, ``robot_vel`` (vx, vy, wz)); ``frame_yaw`` defaults
    to the approach frame (toward ``centre``); ``scan``: the range scan's entries (``SCAN_RAYS``, already divided by
    ``SCAN_RANGE``) to append, None for the 40-entry observation; ``member_order``: one of ``MEMBER_ORDERS``. The
    robot's deploy loop builds its observation with this."""
    x, y, yaw = (float(v) for v in np.asarray(robot_pose, dtype=float)[:3])
    if frame_yaw is None:
        frame_yaw = approach_yaw(robot_pose, centre)
    obs = np.zeros(BASE_SIZE if scan is None else OBS_SIZE, dtype=np.float32)
    v = np.asarray(robot_vel, dtype=float)
    fill_observation(obs, x, y, yaw, float(v[0]), float(v[1]), float(v[2]),
                     np.asarray(members_pos, dtype=float).reshape(-1, 2),
                     np.asarray(members_vel, dtype=float).reshape(-1, 2), float(centre[0]), float(centre[1]),
                     float(radius), float(slot[0]), float(slot[1]), tuple(float(w) for w in walls[:4]),
                     float(max_speed), float(max_yaw_rate), float(frame_yaw), orders_by_bearing(member_order))
    if scan is not None:
        obs[BASE_SIZE:] = np.asarray(scan, dtype=np.float32).reshape(SCAN_RAYS)
    return obs


def orders_by_bearing(member_order: str) -> bool:
    """Whether ``member_order`` (one of ``MEMBER_ORDERS``) orders the members by bearing."""
    if member_order not in MEMBER_ORDERS:
        raise ValueError(f"member_order {member_order!r}: expected one of {list(MEMBER_ORDERS)}")
    return member_order == "bearing"


def obs_size(scan: bool) -> int:
    """Entries of the Vector observation with or without the range scan."""
    return OBS_SIZE if scan else BASE_SIZE


def approach_yaw(robot_pose: np.ndarray, centre: np.ndarray) -> float:
    """Orientation (rad) of the approach frame: from the robot toward the group centre."""
    return math.atan2(float(centre[1] - robot_pose[1]), float(centre[0] - robot_pose[0]))


def decode_members(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Present members' positions (m) and velocities (m/s), in the observation's frame."""
    block = np.asarray(obs[MEMBERS:HEADING], dtype=float).reshape(MAX_MEMBERS, MEMBER_FIELDS)
    present = block[:, MEMBER_PRESENT] > 0.5
    return block[present, MEMBER_X:MEMBER_Y + 1] * POS_SCALE, block[present, MEMBER_VX:MEMBER_VY + 1]


@njit(cache=True)
def action_command(a0: float, a1: float, a2: float, heading_error: float, turn: bool, heading_gain: float,
                   max_speed: float, max_yaw_rate: float) -> tuple[float, float, float]:
    """Body-frame base command (forward m/s, left m/s, turn rad/s) for a normalised action (clipped to [-1, 1]).

    The action is (toward the centre, to the left of that) in the approach frame, and the base turns toward the
    centre at ``heading_gain`` (``heading_error``: rad from the heading to the centre); with ``turn`` it is
    (forward, left, turn) in the body frame."""
    a0, a1 = min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)
    if turn:
        return a0 * max_speed, a1 * max_speed, min(max(a2, -1.0), 1.0) * max_yaw_rate
    w = min(max(heading_gain * heading_error, -max_yaw_rate), max_yaw_rate)
    c, s = math.cos(heading_error), math.sin(heading_error)  # approach frame -> body frame
    return (c * a0 - s * a1) * max_speed, (s * a0 + c * a1) * max_speed, w
