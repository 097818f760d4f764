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


class _Future:
    """A qi future as the watchdog polls it: answered (with or without an error) or not yet."""

    def __init__(self, answered: bool = True, error: bool = False) -> None:
        self.answered, self.error = answered, error

    def isFinished(self) -> bool:  # noqa: N802 - qi's names
        return self.answered

    def hasError(self) -> bool:  # noqa: N802
        return self.error


class _Motion:
    """ALMotion whose stopMove answers as ``answers`` says, in turn (then answers at once)."""

    def __init__(self, *answers: _Future | Exception) -> None:
        self.answers, self.calls = list(answers), 0

    def stopMove(self, _async=False):  # noqa: N802 - NAOqi's name
        self.calls += 1
        answer = self.answers.pop(0) if self.answers else _Future()
        if isinstance(answer, Exception):
            raise answer
        return answer


def test_watchdog_stops_an_armed_base_once_heartbeats_stop():
    from ssbl_pb.deploy.watchdog import Watchdog

    motion = _Motion()
    dog = Watchdog(motion, limit_s=0.5)
    assert dog._expire(100.0) is None  # never armed: a robot driven by something else is left alone
    dog.heartbeat()
    t = dog.last
    assert dog._expire(t + 0.4) is None
    assert dog._expire(t + 0.6) == "sent" and motion.calls == 1
    assert dog._expire(t + 0.62) == "stopped" and dog.stops == 1  # ALMotion answered: confirmed, disarmed
    assert dog._expire(t + 5.0) is None and motion.calls == 1  # once, then disarmed until the next heartbeat
    dog.heartbeat()
    dog.disarm()  # a run that ended normally
    assert dog._expire(dog.last + 5.0) is None and motion.calls == 1


def test_watchdog_stays_armed_and_sends_again_until_a_stop_is_confirmed():
    """Issue 39: a stopMove that times out (no answer) or fails must not end the watchdog: it stays armed and
    sends stopMove again every retry period until ALMotion confirms one."""
    from ssbl_pb.deploy.watchdog import RETRY_S, Watchdog

    lost = _Future(answered=False)  # the first call is never answered (a slow or stalled robot)
    motion = _Motion(lost, _Future(error=True), RuntimeError("Future timeout."), _Future(answered=False))
    dog = Watchdog(motion, limit_s=0.5)
    dog.heartbeat()
    t = dog.last + 0.6
    assert dog._expire(t) == "sent"
    assert dog._expire(t + 0.5 * RETRY_S) is None  # waits one retry period for the answer
    assert dog._expire(t + 1.1 * RETRY_S) == "retry" and motion.calls == 2  # unanswered: sent again
    assert dog._expire(t + 1.2 * RETRY_S) == "retry" and motion.calls == 3  # that one failed: at once again
    assert dog._expire(t + 2.3 * RETRY_S) == "retry" and motion.calls == 4  # raised: still armed, again
    assert dog.armed and dog.stops == 0
    assert dog._expire(t + 3.4 * RETRY_S) == "retry" and motion.calls == 5
    lost.answered = True  # the first call's answer finally arrives: the base is stopped
    assert dog._expire(t + 3.5 * RETRY_S) == "stopped" and dog.stops == 1 and not dog.armed
    assert dog._expire(t + 10.0) is None and motion.calls == 5


def test_watchdog_tick_survives_a_bug_in_a_tick(capsys):
    from ssbl_pb.deploy.watchdog import Watchdog, _tick

    class Broken(Watchdog):
        def _expire(self, now):
            raise ZeroDivisionError("boom")

    _tick(Broken(_Motion(), 0.5), 1.0)  # reports and returns: the loop goes on
    assert "still armed" in capsys.readouterr().err
