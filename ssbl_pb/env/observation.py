"""The Vector observation (paper III-B "Vector" mode): one layout shared by the simulator and the robot.

Everything is relative to the robot and expressed in the *approach frame*: x from the robot toward the group
centre, y to its left. The robot turns to face the centre (as in the original, where it always faces it), so
this is its body frame once it has turned; actions use the same frame, so a turning robot's commands do not
swing around with it. (With ``TaskParams.turn`` the policy steers and the frame is the body frame.) The same
vector is built from the simulator's state or from the tracker's output on the real robot.
Layout (``OBS_SIZE`` = 40):

====  =========================================================  =========
idx   value                                                      scale
====  =========================================================  =========
0-1   free slot position                                         / 5 m
2-3   conversation centre position                               / 5 m
4     o-space radius                                             / 5 m
5-6   robot velocity (forward, left)                             / max speed
7     robot turn rate                                            / max turn rate
8-9   the frame's orientation in the room (cos, sin)             1
10-13 distance to the walls (+x, -x, +y, -y, room frame)         / 5 m
14-38 up to 5 members, nearest first: position (2), velocity     / 5 m, / 1 m/s
      (2), present flag (1); absent members are zeros
39    robot heading minus the frame's (how far it still turns)   / pi
====  =========================================================  =========

The original divides by half its 20 m arena (ref "Vector observation"); our default room is 10 m, so 5 m.
"""

from __future__ import annotations

import math

import numpy as np

MAX_MEMBERS = 5
MEMBER_FIELDS = 5
OBS_SIZE = 14 + MAX_MEMBERS * MEMBER_FIELDS + 1
POS_SCALE = 5.0
OBS_LIMIT = 10.0


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
) -> np.ndarray:
    """Build the observation; ``robot_vel`` is the world-frame (vx, vy, wz), positions are world-frame metres.

    ``frame_yaw`` is the orientation of the frame vectors are expressed in (default: toward ``centre``).
    """
    x, y, yaw = np.asarray(robot_pose, dtype=float)[:3].tolist()
    if frame_yaw is None:
        frame_yaw = approach_yaw(robot_pose, centre)
    c, s = math.cos(frame_yaw), math.sin(frame_yaw)

    def to_frame(dx: float, dy: float, scale: float) -> tuple[float, float]:
        return (c * dx + s * dy) / scale, (c * dy - s * dx) / scale

    members_pos = np.asarray(members_pos, dtype=float).reshape(-1, 2)
    k = min(len(members_pos), MAX_MEMBERS)
    rel = members_pos - (x, y)
    order = np.argsort(np.einsum("ij,ij->i", rel, rel), kind="stable")[:k]
    (sx, sy), (cx, cy), (vx, vy, wz) = slot[:2].tolist(), centre[:2].tolist(), robot_vel[:3].tolist()
    obs = np.zeros(OBS_SIZE, dtype=np.float32)
    obs[0:14] = (*to_frame(sx - x, sy - y, POS_SCALE), *to_frame(cx - x, cy - y, POS_SCALE), radius / POS_SCALE,
                 *to_frame(vx, vy, max_speed), wz / max_yaw_rate, c, s, *(np.asarray(walls) / POS_SCALE).tolist())
    # members' positions and velocities (world frame) -> frame, one matrix product
    vecs = np.concatenate([rel[order], np.asarray(members_vel, dtype=float).reshape(-1, 2)[order]])
    body = vecs @ np.array([[c, -s], [s, c]])
    block = obs[14:14 + MAX_MEMBERS * MEMBER_FIELDS].reshape(MAX_MEMBERS, MEMBER_FIELDS)
    block[:k, 0:2] = body[:k] * (1.0 / POS_SCALE)
    block[:k, 2:4] = body[k:]
    block[:k, 4] = 1.0
    obs[39] = math.remainder(yaw - frame_yaw, 2.0 * math.pi) / math.pi
    np.maximum(obs, -OBS_LIMIT, out=obs)
    return np.minimum(obs, OBS_LIMIT, out=obs)


def approach_yaw(robot_pose: np.ndarray, centre: np.ndarray) -> float:
    """Orientation (rad) of the approach frame: from the robot toward the group centre."""
    return math.atan2(float(centre[1] - robot_pose[1]), float(centre[0] - robot_pose[0]))


def decode_members(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Present members' positions (m) and velocities (m/s), in the observation's frame."""
    block = np.asarray(obs[14:39], dtype=float).reshape(MAX_MEMBERS, MEMBER_FIELDS)
    present = block[:, 4] > 0.5
    return block[present, 0:2] * POS_SCALE, block[present, 2:4]
