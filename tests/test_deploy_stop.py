"""Deploy's own stop and release of a Pepper, without qi: ``NaoqiRobot`` on fake services whose calls answer,
fail or time out as each test says. The stop is tried again for up to ``stop_retry_s``; once a stop is answered,
``close`` disarms the watchdog and releases the camera even after an earlier call timed out."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from ssbl_pb.deploy.faults import ConnectionLost, RobotNotResponding
from ssbl_pb.deploy.naoqi import NaoqiParams, NaoqiRobot
from ssbl_pb.params import RobotParams


class Call:
    """A qi future: ``value`` returns, or raises as libqi does on a timeout."""

    def __init__(self, result=None, hang=False):
        self.result, self.hang = result, hang

    def value(self, timeout_ms=None):
        if self.hang:
            raise RuntimeError("Future timeout.")
        return self.result


class Service:
    """Any method: logs its name in ``calls``; the names in ``hang`` time out, once each listed time."""

    def __init__(self, calls, hang=(), result=None):
        self.calls, self.hang, self.result = calls, list(hang), result

    def __getattr__(self, name):
        def call(*args, _async=False):
            self.calls.append(name)
            hung = name in self.hang
            if hung:
                self.hang.remove(name)
            return Call(self.result, hang=hung)

        return call


class Session:
    def isConnected(self):  # noqa: N802 - qi's name
        return True

    def close(self):
        pass


def robot(calls, hang=(), watchdog=True, sonar=False):
    """A connected NaoqiRobot with a subscribed camera, (``watchdog``) an armed watchdog and (``sonar``) ALSonar
    subscribed."""
    r = NaoqiRobot.__new__(NaoqiRobot)
    r.url, r.limits, r.p = "tcp://fake:9559", RobotParams(), NaoqiParams()
    r.lost, r.unresponsive, r.stopped, r.closed = threading.Event(), False, False, False
    r.identity, r.move_failed, r._subscribers = None, [], []
    r.session = Session()
    r.motion = Service(calls, hang, result=[0.0, 0.0, 0.0])
    r.video = Service(calls, hang)
    r.watchdog = Service(calls, hang) if watchdog else None
    r.handle = "ssbl_deploy_0"
    r.sonar = Service(calls, hang) if sonar else None
    return r


def test_close_releases_the_robot_after_a_timed_out_call_once_a_stop_was_answered():
    calls = []
    r = robot(calls, hang=["getRobotPosition"])
    r.send(np.array([0.2, 0.0, 0.0]))
    with pytest.raises(RobotNotResponding):
        r.odometry()  # a stall: deploy's run ends on it
    assert r.unresponsive
    r.stop()  # the robot answers again
    r.close()
    assert calls[-2:] == ["disarm", "unsubscribe"]
    assert calls.count("stopMove") == 1  # close does not stop again a base already stopped


def test_deploys_stop_is_tried_again_until_one_is_answered():
    calls = []
    r = robot(calls, hang=["stopMove", "stopMove"], sonar=True)  # two lost stops (a stalled network)
    r.send(np.array([0.2, 0.0, 0.0]))
    r.stop()
    assert calls.count("stopMove") == 3 and r.stopped and not r.unresponsive
    r.close()
    assert "disarm" in calls and calls.count("unsubscribe") == 2  # the camera's and ALSonar's, after the stop
    assert calls.index("unsubscribe") > max(i for i, c in enumerate(calls) if c == "stopMove")


def test_a_stop_never_answered_gives_up_after_its_bound_and_close_tries_nothing_more():
    calls = []
    r = robot(calls, hang=["stopMove"] * 1000)
    r.p = NaoqiParams(call_timeout_s=0.01, stop_retry_s=0.1)
    r.send(np.array([0.2, 0.0, 0.0]))
    with pytest.raises(RobotNotResponding):
        r.stop()
    assert calls.count("stopMove") >= 2  # several bounded tries
    n = len(calls)
    r.close()
    assert len(calls) == n  # frozen: no disarm (the watchdog stays armed and stops the base), no more calls


def test_a_lost_connection_ends_the_stop_at_once():
    calls = []
    r = robot(calls)
    r.lost.set()
    with pytest.raises(ConnectionLost):
        r.stop()
    assert calls == []
