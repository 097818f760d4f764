"""Deploy's robot side without qi: the command clamp, poses, the simulated robot and its lockstep clock."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.deploy.frames import Frames, inverse, transform_points
from ssbl_pb.deploy.robot import clamp_command, compose, relative
from ssbl_pb.params import RobotParams
from ssbl_pb.virtual.robot import SimClock, SimRobot


def test_clamp_limits_planar_speed_as_a_vector_and_the_turn_rate():
    limits = RobotParams(max_speed=0.2, max_yaw_rate=0.5)
    out = clamp_command(np.array([0.3, 0.4, -2.0]), limits)
    assert out == pytest.approx([0.12, 0.16, -0.5])  # |(0.3, 0.4)| = 0.5 -> scaled to 0.2, direction kept
    assert clamp_command(np.array([0.1, 0.0, 0.2]), limits) == pytest.approx([0.1, 0.0, 0.2])


@pytest.mark.parametrize("bad", [[np.nan, 0, 0], [0, np.inf, 0], [0.1, 0.1], [0.1, 0.1, 0.1, 0.1]])
def test_clamp_turns_anything_malformed_into_a_stop(bad):
    assert clamp_command(np.array(bad, dtype=float), RobotParams()).tolist() == [0.0, 0.0, 0.0]


def test_compose_and_relative_are_inverse():
    a, b = np.array([1.0, -2.0, 2.5]), np.array([0.3, 0.7, -1.0])
    ab = compose(a, b)
    assert relative(a, ab) == pytest.approx(b)
    assert compose(a, inverse(a)) == pytest.approx([0, 0, 0], abs=1e-12)
    # a point 1 m ahead of a robot at (1, 2) facing +y is at (1, 3)
    assert transform_points(np.array([1.0, 2.0, math.pi / 2]), np.array([[1.0, 0.0]]))[0] == pytest.approx([1, 3])


def test_sim_robot_keeps_the_last_command_until_stopped():
    robot = SimRobot("default", seed=4)
    try:
        assert robot.odometry().pose == pytest.approx([0, 0, 0])  # odometry starts at the spawn pose
        sent = robot.send(np.array([0.5, 0.0, 0.0]))
        assert sent == pytest.approx([0.35, 0.0, 0.0])  # the NAOqi default limit
        robot.advance(3.0)
        odo = robot.odometry()
        assert odo.velocity[0] == pytest.approx(0.35, abs=1e-6)  # still moving 3 s later
        assert odo.pose[0] > 0.7 and abs(odo.pose[1]) < 1e-6  # forward in its own frame
        room = compose(robot.start_pose, odo.pose)
        assert room == pytest.approx(robot.world.robot_pose)
        robot.stop()
        robot.advance(2.0)
        assert robot.odometry().velocity == pytest.approx([0, 0, 0], abs=1e-9)  # 0.35 m/s at 0.3 m/s^2: 1.2 s
    finally:
        robot.close()


def test_sim_clock_advances_time_and_renders_at_its_rate():
    robot = SimRobot("default", seed=4, image_size=(80, 60))
    try:
        clock = SimClock(robot, fps=10.0)
        first = robot.frame()
        assert first is not None and first.image.shape == (60, 80, 3) and first.stamp == 0.0
        clock.sleep(0.1)
        assert clock.now() == pytest.approx(0.1) and robot.frame().stamp == pytest.approx(0.1)
        assert robot.odometry().stamp == pytest.approx(0.1)  # odometry is stamped on the same clock
    finally:
        robot.close()


def test_frames_without_a_map_are_odometry_with_no_walls_near():
    fr = Frames()
    fr.anchor(np.array([2.0, 1.0, 0.3]))
    pose = np.array([0.5, -0.5, 1.0])
    assert fr.room_pose(pose) == pytest.approx(pose) and fr.map_pose(pose) is None
    assert fr.walls(pose).tolist() == [5.0, 5.0, 5.0, 5.0]  # the middle of the 10 m training room
