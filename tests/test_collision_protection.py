"""Over qi against the virtual Pepper: its ALMemory serves the base's lasers and sonars under NAOqi's keys, its
ALMotion the external collision protection switch; deploy reads the former and refuses to run with the latter off
unless told ``--allow-collision-protection-off``."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("qi")

from ssbl_pb.bench.deploy import virtual_pepper  # noqa: E402
from ssbl_pb.deploy.naoqi import NaoqiRobot, RobotError  # noqa: E402
from ssbl_pb.deploy.ranges import KEYS  # noqa: E402
from ssbl_pb.params import RobotParams  # noqa: E402


def _deploy(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ssbl_pb.deploy", "--policy", "sffm", "--detector", "colour",
                           "--no-watchdog", "--quiet", "--duration", "1", *argv],
                          capture_output=True, text=True, timeout=60)


def test_the_virtual_pepper_serves_the_range_sensors_and_the_protection_switch(tmp_path):
    import qi

    with virtual_pepper(tmp_path / "vp.jsonl", 3) as (_, url):
        robot = NaoqiRobot(url, RobotParams())
        try:
            assert robot.protection is True  # on, as a Pepper starts
            scan = robot.ranges()
            assert scan is not None and scan.points.ndim == 2 and len(scan.points) and scan.sonars <= 2
            session = qi.Session()
            session.connect(url)
            memory, motion = session.service("ALMemory"), session.service("ALMotion")
            values = memory.getListData(list(KEYS))
            assert len(values) == 92 and all(isinstance(v, float) for v in values)
            assert memory.getData(KEYS[-1]) == pytest.approx(values[-1])
            with pytest.raises(RuntimeError, match="no data for key"):
                memory.getData("Device/SubDeviceList/Platform/Nothing")
            motion.setExternalCollisionProtectionEnabled("All", False)
            assert not motion.getExternalCollisionProtectionEnabled("Move")
            motion.setExternalCollisionProtectionEnabled("Move", True)
            assert motion.getExternalCollisionProtectionEnabled("Move")
            assert not motion.getExternalCollisionProtectionEnabled("Arms")
            session.close()
        finally:
            robot.close()
        assert np.isfinite(scan.points).all()


def test_deploy_refuses_a_robot_whose_collision_protection_is_off_unless_told(tmp_path):
    with virtual_pepper(tmp_path / "vp.jsonl", 35, "default", "--collision-protection-off") as (_, url):
        with pytest.raises(RobotError, match="collision protection"):
            NaoqiRobot(url, RobotParams())
        res = _deploy("--url", url, "--log-dir", str(tmp_path / "run"))
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1, res.stderr
        assert 'getExternalCollisionProtectionEnabled("Move")' in lines[0] and "is off" in lines[0]
        assert 'setExternalCollisionProtectionEnabled("Move", True)' in lines[0]
        assert "--allow-collision-protection-off" in lines[0] and not (tmp_path / "run").exists()
        res = _deploy("--url", url, "--log-dir", str(tmp_path / "run"), "--allow-collision-protection-off")
    assert res.returncode == 3, res.stderr  # ran until its --duration
    assert (tmp_path / "run" / "log.jsonl").is_file()


def test_deploy_runs_the_sonars_while_it_runs_and_the_virtual_pepper_holds_their_last_echo_without(tmp_path):
    from types import SimpleNamespace

    from ssbl_pb.core.range_sensors import RANGES, SONARS
    from ssbl_pb.deploy.naoqi import SONAR_SUBSCRIBER
    from ssbl_pb.deploy.ranges import SONAR_KEY
    from ssbl_pb.virtual.robot import SimRobot
    from ssbl_pb.virtual.services import make_services
    from ssbl_pb.virtual.walkers import Stranger

    robot = SimRobot("default", 0)
    try:  # the services in process: one member 1.5 m straight ahead of the robot at the room's centre
        vp = SimpleNamespace(robot=robot, sonar_subscribers=set(), sonar_held={}, write=lambda row: None)
        _, _, memory, sonar = make_services(vp)
        robot.world.base.pose = np.zeros(3)
        robot.world.group.pos[:] = [[1.5, 0.0], [0.0, 3.0]]
        robot.world.invalidate()
        front = SONAR_KEY.format("Front")
        assert memory.getData(front) == RANGES.sonar_reported_max  # nobody subscribed: the sonars never ran
        sonar.subscribe("test")
        echo = 1.5 - 0.28 - SONARS["Front"].x  # the member's near side, from the sonar
        assert memory.getData(front) == pytest.approx(echo, abs=3e-3)
        sonar.unsubscribe("test")
        stranger = Stranger()  # someone steps in 1 m ahead; the sonars no longer run ...
        robot.add_walker(stranger)
        stranger.pos, stranger.phase = np.array([1.0, 0.0]), "done"
        robot.advance(2.0 / RANGES.sonar_hz)
        assert memory.getListData([front])[0] == pytest.approx(echo, abs=3e-3)  # ... ALMemory holds the old echo
        sonar.subscribe("test")
        assert memory.getData(front) == pytest.approx(echo - 0.5, abs=3e-3)
    finally:
        robot.close()
    log = tmp_path / "vp.jsonl"
    with virtual_pepper(log, 3) as (_, url):  # over qi: deploy subscribes as it connects and unsubscribes as it closes
        deployed = NaoqiRobot(url, RobotParams())
        try:
            assert deployed.sonar is not None
        finally:
            deployed.close()
    from ssbl_pb.virtual.pepper import load_log

    calls = [(c["call"], c.get("name")) for c in load_log(log)[2] if c["kind"] == "call" and "Sonar" in c["call"]]
    assert calls == [("ALSonar.subscribe", SONAR_SUBSCRIBER), ("ALSonar.unsubscribe", SONAR_SUBSCRIBER)]
