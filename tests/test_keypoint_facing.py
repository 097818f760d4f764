"""Facing and range from body keypoints (perception.detection.keypoints, keypoint_range): synthetic keypoints of a
person placed by hand (the template's points at a known yaw, projected by a pinhole), read back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.errors import UserError
from ssbl_pb.perception.camera import PinholeCamera
from ssbl_pb.perception.detection.keypoint_range import range_keypoints
from ssbl_pb.perception.detection.keypoints import (
    BodyParams,
    FacingTrack,
    facing_from_keypoints,
    facing_posterior,
    silhouette,
    yaw_grid,
)
from ssbl_pb.perception.detection.ranging import PinholeGeometry, RangingParams, range_boxes

P = BodyParams()


def camera(height: float = 1.15, pitch: float = 0.0, f: float = 600.0) -> PinholeGeometry:
    """A 640 x 480 pinhole at the origin, ``height`` m up, looking along +x, tilted down by ``pitch`` deg."""
    k = np.array([[f, 0.0, 320.0], [0.0, f, 240.0], [0.0, 0.0, 1.0]])
    return PinholeGeometry(PinholeCamera(640, 480, k, camera_height=height, pitch_deg=pitch, forward=0.0))


def body(yaw: float, shoulders: tuple[tuple[float, float], tuple[float, float]] | None = None,
         hips: tuple[tuple[float, float], tuple[float, float]] | None = None, scale: float = 1.0) -> np.ndarray:
    """The 17 keypoints in the body frame (forward, left, up; m), the limbs' NaN: the template's numbers written
    out (``BodyParams``), heights times ``scale``; shoulders and hips (left, right) at the joints unless given."""
    pts = np.full((17, 3), np.nan)
    pts[0] = (0.11, 0.0, 1.60)
    pts[1], pts[2] = (0.093, 0.024, 1.64), (0.093, -0.024, 1.64)
    pts[3], pts[4] = (0.028, 0.056, 1.61), (0.028, -0.056, 1.61)
    sh = shoulders or ((-0.02, 0.16), (-0.02, -0.16))
    hp = hips or ((-0.035, 0.095), (-0.035, -0.095))
    pts[5], pts[6] = (*sh[0], 1.42), (*sh[1], 1.42)
    pts[11], pts[12] = (*hp[0], 0.91), (*hp[1], 0.91)
    pts[:, 2] *= scale
    return pts


def keypoints(geom: PinholeGeometry, xy: tuple[float, float], yaw: float, pts: np.ndarray,
              face: float = 0.9) -> np.ndarray:
    """``pts`` (body frame) of a person at ``xy`` facing ``yaw`` -> keypoints (17, 3): pixels and scores (0.9;
    the nose and eyes ``face``; the limbs 0)."""
    c, s = math.cos(yaw), math.sin(yaw)
    world = np.column_stack([xy[0] + c * pts[:, 0] - s * pts[:, 1], xy[1] + s * pts[:, 0] + c * pts[:, 1],
                             pts[:, 2]])
    out = np.zeros((17, 3))
    ok = np.isfinite(world).all(axis=1)
    out[ok, :2] = geom.world_to_image(world[ok])
    out[ok, 2] = 0.9
    out[[0, 1, 2], 2] = face
    return out


def angle_deg(a: float, b: float) -> float:
    return abs(math.degrees(math.remainder(a - b, 2 * math.pi)))


def test_front_and_back_by_hand_on_a_robots_camera():
    # 2 m ahead of a camera at Pepper's height: 300 px per metre, the face's points seen or not count. Facing the
    # camera (yaw pi): left shoulder on the image's right; the back (yaw 0): the face's points not found
    geom, xy = camera(), (2.0, 0.0)
    front = keypoints(geom, xy, math.pi, body(math.pi))
    assert front[5, 0] > front[6, 0]  # the person's left on the image's right
    back = keypoints(geom, xy, 0.0, body(0.0), face=0.05)
    est = facing_from_keypoints(geom, np.stack([front, back]), np.array([xy, xy]), P)
    assert angle_deg(est.yaw[0], math.pi) < 10 and angle_deg(est.yaw[1], 0.0) < 10
    assert abs(est.phi[0]) < math.radians(10) and est.std[0] < math.radians(30)  # phi 0: looks at the camera
    # the network swapped a back view's labels (it looks like a front view then): the face not found tells the back
    swapped = back[[0, 2, 1, 4, 3, 6, 5, 7, 8, 9, 10, 12, 11, 13, 14, 15, 16]]
    assert angle_deg(facing_from_keypoints(geom, swapped[None], np.array([xy]), P).yaw[0], 0.0) < 15


def test_side_view_by_hand():
    # seen from their left (facing +y, 3 m ahead): the network's shoulders and hips on the body's outline, the
    # chest's front and back (``silhouette``: the left one on the front here); the nose ahead tells which way
    geom, xy, yaw = camera(), (3.0, 0.0), math.pi / 2
    view = np.array([[0.0, -1.0]])  # camera -> person in the body frame: along -y (the camera on their left)
    edges = silhouette(view, 0.16, 0.13)[0]
    np.testing.assert_allclose(edges, [[0.13, 0.0], [-0.13, 0.0]], atol=1e-12)
    pts = body(yaw, shoulders=((-0.02 + 0.13, 0.0), (-0.02 - 0.13, 0.0)),
               hips=((-0.035 + 0.13, 0.0), (-0.035 - 0.13, 0.0)))
    est = facing_from_keypoints(geom, keypoints(geom, xy, yaw, pts)[None], np.array([xy]), P)
    assert angle_deg(est.yaw[0], yaw) < 15
    # and turned the other way (facing -y, the camera on their right), mirrored
    pts = body(-yaw, shoulders=((-0.02 - 0.13, 0.0), (-0.02 + 0.13, 0.0)),
               hips=((-0.035 - 0.13, 0.0), (-0.035 + 0.13, 0.0)))
    est = facing_from_keypoints(geom, keypoints(geom, xy, -yaw, pts)[None], np.array([xy]), P)
    assert angle_deg(est.yaw[0], -yaw) < 15


def test_small_people_from_above_by_their_left_and_right():
    # a camera 7 m up looking 15 deg down at people 25 m away (45 px per metre, as PETS): the face is too small to
    # count, the labels of the shoulders and hips tell front from back; every yaw read within 20 deg
    geom, xy = camera(7.0, 15.0), (25.0, 2.0)
    for yaw_deg in (0, 45, 135, 180, -135, -45):
        yaw = math.radians(yaw_deg)
        view = np.array([xy[0], xy[1]]) / np.hypot(*xy)  # camera -> person, world frame
        v_body = np.array([[math.cos(yaw) * view[0] + math.sin(yaw) * view[1],
                            -math.sin(yaw) * view[0] + math.cos(yaw) * view[1]]])
        sh, hp = silhouette(v_body, 0.16, 0.13)[0], silhouette(v_body, 0.095, 0.13)[0]
        pts = body(yaw, shoulders=tuple(map(tuple, sh + [-0.02, 0.0])), hips=tuple(map(tuple, hp + [-0.035, 0.0])))
        est = facing_from_keypoints(geom, keypoints(geom, xy, yaw, pts, face=0.9)[None], np.array([xy]), P)
        assert angle_deg(est.yaw[0], yaw) < 20, yaw_deg


def test_too_few_points_say_nothing():
    geom, xy = camera(), (2.0, 0.0)
    kp = keypoints(geom, xy, math.pi, body(math.pi))
    kp[[5, 6, 11, 12], 2] = 0.0  # no shoulder or hip seen
    post, ok = facing_posterior(geom, kp[None], np.array([xy]), P)
    assert not ok[0] and np.allclose(post, 1.0 / len(yaw_grid(P)))
    assert math.isnan(facing_from_keypoints(geom, kp[None], np.array([xy]), P).yaw[0])
    with pytest.raises(UserError, match="keypoints.swap_rate"):
        BodyParams(swap_rate=1.0)
    with pytest.raises(UserError, match=r"keypoints.torso_depth = \(0.1,\): expected two numbers"):
        BodyParams(torso_depth=(0.1,))


def test_a_track_keeps_its_facing_through_frames_that_cannot_tell_front_from_back():
    grid = yaw_grid(P)
    track = FacingTrack(P, turn_std=0.75, floor=0.05)
    sharp = np.exp(-0.5 * (np.angle(np.exp(1j * (grid - 1.0))) / 0.2) ** 2)
    for _ in range(3):
        track.predict(1 / 7)
        track.update(sharp / sharp.sum())
    yaw, std = track.estimate()
    assert angle_deg(yaw, 1.0) < 3 and std < math.radians(20)
    both = sharp + np.exp(-0.5 * (np.angle(np.exp(1j * (grid - 1.0 - math.pi))) / 0.2) ** 2)  # front or back
    for _ in range(5):
        track.predict(1 / 7)
        track.update(both / both.sum())
    assert angle_deg(track.estimate()[0], 1.0) < 3
    assert math.isnan(FacingTrack(P, 0.75).estimate()[0])  # nothing seen yet


def test_range_from_the_rows_by_hand():
    # a level camera 1.15 m up, f = 600 px: a person 4 m ahead facing it shows the eyes (0.093 m ahead of the axis)
    # at v = 240 - 600 (1.64 - 1.15) / 3.907 = 164.75, the hips (0.035 m behind) at 240 + 600 * 0.24 / 4.035 =
    # 275.69. Ranged within 4 cm (the facing given: the face ahead of the shoulders, their width) or without it.
    # The level camera's rows say little about the range (0.35 m at 4 m, along the line of sight): a person 8 %
    # taller than the prior is ranged within that, nearer (the prior's stature pulls)
    geom = camera()
    kp = keypoints(geom, (4.0, 0.0), math.pi, body(math.pi))
    assert kp[1, 1] == pytest.approx(164.75, abs=0.01) and kp[11, 1] == pytest.approx(275.69, abs=0.01)
    tall = keypoints(geom, (3.0, 1.5), math.pi, body(math.pi, scale=1.08))
    facing = np.array([math.pi, math.pi])
    xy, cov, ok = range_keypoints(geom, np.stack([kp, tall]), P, facing, np.full(2, 0.1))
    assert ok.all()
    np.testing.assert_allclose(xy[0], [4.0, 0.0], atol=0.04)
    d = np.hypot(*xy[1]) - np.hypot(3.0, 1.5)
    assert -math.sqrt(np.trace(cov[1])) < d < 0
    np.testing.assert_allclose(range_keypoints(geom, kp[None], P)[0][0], [4.0, 0.0], atol=0.04)
    u = np.array([3.0, 1.5]) / np.hypot(3.0, 1.5)
    along, across = u @ cov[1] @ u, np.array([-u[1], u[0]]) @ cov[1] @ np.array([-u[1], u[0]])
    assert along > 4 * across > 0


def test_range_from_the_shoulders_width_where_the_facing_is_known():
    # only the shoulders seen (head and hips hidden): one row cannot fix both range and stature, their width can:
    # 0.32 m at 5 m is 38.4 px; with the facing (the person faces the camera) it gives 5 m, without it nothing
    geom = camera()
    kp = keypoints(geom, (5.0, 0.0), math.pi, body(math.pi))
    assert kp[5, 0] - kp[6, 0] == pytest.approx(600 * 0.32 / 5.02)  # the shoulders 0.02 m behind the axis
    kp[[0, 1, 2, 3, 4, 11, 12], 2] = 0.0
    xy, _, ok = range_keypoints(geom, kp[None], P, yaw=np.array([math.pi]), yaw_std=np.array([0.05]))
    assert ok[0] and np.hypot(*(xy[0] - [5.0, 0.0])) < 0.3
    assert not range_keypoints(geom, kp[None], P)[2][0]


def test_a_cut_movenet_box_is_ranged_from_its_keypoints_not_its_top():
    # MoveNet's box starts at the eyes: taken as the head top (1.76 m), a person 3 m away comes out 0.4 m nearer
    geom = camera()
    kp = keypoints(geom, (3.0, 0.0), math.pi, body(math.pi))
    top, bottom = kp[1, 1], 480.0  # from the eyes to the image's bottom (feet out of view)
    box = np.array([[kp[6, 0] - 10, top, kp[5, 0] - kp[6, 0] + 20, bottom - top, 0.9]])
    by_box, _, _ = range_boxes(geom, box, 480, RangingParams(keypoints=False))
    by_kp, _, cue = range_boxes(geom, box, 480, RangingParams(), kp[None])
    faced, _, _ = range_boxes(geom, box, 480, RangingParams(), kp[None], yaw=np.array([math.pi]),
                              yaw_std=np.array([0.1]))
    assert cue[0] == 1 and abs(by_box[0, 0] - 3.0) > 0.3
    assert abs(by_kp[0, 0] - 3.0) < 0.04 and abs(faced[0, 0] - 3.0) < 0.04
