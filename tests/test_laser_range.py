"""Ranging detected people by the base's lasers (``perception.detection.laser_range``)."""

import math

import numpy as np
import pytest

from ssbl_pb.perception.detection.laser_range import LEG_DEPTH_M, laser_ranged


def test_a_person_moves_along_the_bearing_to_the_depth_behind_the_nearest_return():
    # the camera puts a person 2.4 m out at 30 deg; the lasers hit them at 2.0 m at 29 and 32 deg (both within
    # their 0.25 m half-width of the nearest) and a wall 2.95 m away behind: the person's centre is 2.0 + depth out,
    # at the two returns' mean bearing, 30.5 deg
    ray = lambda deg, r: r * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])  # noqa: E731
    points = np.array([ray(29.0, 2.0), ray(32.0, 2.05), ray(30.0, 2.95)])
    xy, hit = laser_ranged(np.array([ray(30.0, 2.4), [np.nan, np.nan]]), points, depth=0.28)
    assert hit.tolist() == [True, False]
    assert xy[0].tolist() == pytest.approx(ray(30.5, 2.0 + 0.28).tolist())
    assert np.isnan(xy[1]).all()


def test_returns_off_the_bearing_or_outside_the_gate_leave_the_camera_range():
    xy = np.array([[2.0, 0.0]])
    beside = np.array([[1.8, 0.5]])  # 0.5 m to the side: another person
    far_in_front = np.array([[0.5, 0.0]])  # 1.4 m nearer (with the depth): near gate max(0.5, 0.65 * 2.0) m
    for pts in (beside, far_in_front, np.zeros((0, 2))):
        out, hit = laser_ranged(xy, pts)
        assert not hit.any() and out.tolist() == xy.tolist()
    out, hit = laser_ranged(xy, np.array([[1.6, 0.0]]))  # 0.3 m nearer, inside the gate
    assert hit.all() and out[0].tolist() == pytest.approx([1.6 + LEG_DEPTH_M, 0.0])


def test_deploy_takes_the_depth_a_virtual_pepper_names_and_a_real_pepper_s_feet_otherwise():
    from types import SimpleNamespace

    from ssbl_pb.deploy.perceive import Perception
    from ssbl_pb.errors import UserError

    real = Perception(SimpleNamespace(identity=None), lambda: 0.0, "colour", threaded=False)
    virtual = Perception(SimpleNamespace(identity={"person_laser_depth_m": "0.28"}), lambda: 0.0, "colour",
                         threaded=False)
    assert real.laser_depth == LEG_DEPTH_M == 0.1 and virtual.laser_depth == 0.28
    # the loop hands the lasers' robot-frame returns over at the odometry pose: stored in the odometry frame
    real.ranges(np.array([[1.0, 0.0]]), np.array([2.0, 1.0, math.pi / 2]))
    assert real.scan[0].tolist() == pytest.approx([2.0, 2.0])

    with pytest.raises(UserError, match="person_laser_depth_m = 'far': expected metres in \\[0, 1\\]"):
        Perception(SimpleNamespace(identity={"person_laser_depth_m": "far"}), lambda: 0.0, "colour", threaded=False)


def test_movenet_boxes_near_the_image_side_are_cut_bodies():
    from ssbl_pb.deploy.perceive import BODY_MARGIN, whole_people  # BODY_MARGIN: keypoint_range's

    # 150 px tall: 1 + 0.07 * 150 = 11.5 px must stay clear of either side of a 320 px image
    boxes = np.array([[11.0, 40, 50, 150], [12.0, 40, 50, 150], [258.0, 40, 50, 150], [259.0, 40, 50, 150]])
    assert BODY_MARGIN == 0.07
    assert whole_people(boxes, 320, BODY_MARGIN).tolist() == [False, True, True, False]
    assert whole_people(boxes, 320).tolist() == [True, True, True, True]  # HOG's: only a box at the side is cut
    assert whole_people(np.zeros((0, 5)), 320, BODY_MARGIN).shape == (0,)


def test_a_keypoint_range_too_far_takes_the_return_nearest_it_within_the_near_gate():
    # MoveNet's keypoints put a person at 3.1 m who stands at 2.0 m: the return at 1.9 m is 1.1 m nearer (with the
    # depth), inside the near gate max(0.5, 0.65 * 3.1 = 2.02) m (beyond it only max(0.5, 0.3 * 3.1 = 0.93) m counts)
    out, hit = laser_ranged(np.array([[3.1, 0.0]]), np.array([[1.9, 0.0]]))
    assert hit.all() and out[0].tolist() == pytest.approx([1.9 + LEG_DEPTH_M, 0.0])
    out, hit = laser_ranged(np.array([[3.1, 0.0]]), np.array([[1.3, 0.0]]))  # 1.7 m nearer: inside it too
    assert hit.all() and out[0].tolist() == pytest.approx([1.3 + LEG_DEPTH_M, 0.0])
    out, hit = laser_ranged(np.array([[3.1, 0.0]]), np.array([[0.9, 0.0]]))  # 2.1 m nearer: outside it
    assert not hit.any()
    out, hit = laser_ranged(np.array([[2.0, 0.0]]), np.array([[3.0, 0.0]]))  # 0.9 m beyond: outside max(0.5, 0.6)
    assert not hit.any()
    # someone in front (legs at 1.9 m, inside the near gate of 2.15 m) and the person behind them (2.9 and 3.0 m,
    # two legs), the camera at 3.3 m: the return nearest the camera's range is the person's (not the nearest
    # return), their near side the nearest of their own returns
    pts = np.array([[1.9, 0.02], [2.9, 0.0], [3.0, 0.05]])
    out, hit = laser_ranged(np.array([[3.3, 0.0]]), pts)
    assert hit.all() and math.hypot(*out[0]) == pytest.approx(2.9 + LEG_DEPTH_M)
