"""The real NAOqi path over qi against the virtual Pepper on loopback (a free port per test): the robot interface,
each fault of the benchmark (exit code names it; the virtual base's command is zero within 0.8 s per its own log),
the watchdog it serves, and robots that cannot be used. Whole approaches over qi are the benchmark's
(tools/bench_deploy.py): real time is slow."""

from __future__ import annotations

import json
import math
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytest.importorskip("qi")

from ssbl_pb.bench.deploy import start_deploy, stop_times, virtual_pepper, wait_moving  # noqa: E402
from ssbl_pb.bench.deploy_faults import FAULTS, WALKER_FAULTS, WATCHED, run_fault  # noqa: E402
from ssbl_pb.deploy.naoqi import NaoqiRobot, RobotError  # noqa: E402
from ssbl_pb.params import RobotParams  # noqa: E402
from ssbl_pb.virtual.pepper import load_log  # noqa: E402


def test_robot_interface_over_qi(tmp_path):
    log = tmp_path / "vp.jsonl"
    with virtual_pepper(log, seed=3) as (_, url):
        for _ in range(7):  # NAOqi allows 6 subscriptions per name: only works if each run unsubscribes
            robot = NaoqiRobot(url, RobotParams(max_speed=0.2))
            robot.close()
        robot = NaoqiRobot(url, RobotParams(max_speed=0.2))
        try:
            assert robot.watchdog is not None and robot.identity is not None  # the virtual Pepper serves both
            time.sleep(0.3)
            frame = robot.frame()
            assert frame.image.shape == (240, 320, 3) and frame.image.dtype == np.uint8
            assert frame.image.std() > 10  # a rendered scene, not the bytes' text repr
            assert robot.odometry().pose == pytest.approx([0, 0, 0], abs=1e-9)
            assert robot.send(np.array([0.5, 0.0, 0.0])) == pytest.approx([0.2, 0.0, 0.0])  # our clamp
            for _ in range(15):  # commands (and heartbeats) at 10 Hz, as deploy sends them
                time.sleep(0.1)
                robot.send(np.array([0.5, 0.0, 0.0]))
            odo = robot.odometry()
            assert odo.velocity[0] == pytest.approx(0.2, abs=1e-6) and odo.pose[0] > 0.1
            robot.stop()
            time.sleep(1.0)  # 0.2 m/s at 0.3 m/s^2: 0.67 s to stand still
        finally:
            robot.close()
    _, states, calls = load_log(log)
    names = [c.get("call") for c in calls]
    assert names.count("subscribeCamera") == 8 and names.count("unsubscribe") == 8
    assert states[-1]["cmd"] == [0.0, 0.0, 0.0] and states[-1]["vel"] == pytest.approx([0, 0, 0], abs=1e-9)


EXPECTED = {"robot_killed": 7, "camera_frozen": 5, "odometry_frozen": 6, "robot_frozen": 8, "sigint": 130,
            "sigterm": 143, "sighup": 143, "policy_exception": 1, "deploy_killed": -9, "watchdog_stop_hangs": -9}
BOUND_S = 0.8  # the base's command zero within this of the fault, by the virtual Pepper's own log


@pytest.mark.slow
@pytest.mark.parametrize("fault", [f for f in FAULTS if f not in WALKER_FAULTS])  # those: test_range_sensors.py
def test_each_fault_stops_the_base_and_names_itself(fault, tmp_path):
    # a loaded machine may deliver a frame a second or more late: the staleness limit is raised, and raised
    # further where staleness is not what the fault is about (a late frame once ended policy_exception first)
    stale = 2.0 if fault in ("camera_frozen", "robot_frozen", "odometry_frozen") else 6.0
    res = run_fault(fault, tmp_path, stale=stale)
    assert res["exit_code"] == EXPECTED[fault], res
    assert not res.get("hung"), res
    written = tmp_path / "deploy" / "summary.json"  # (deploy killed writes none; policy_exception runs no CLI)
    summary = json.loads(written.read_text()) if written.is_file() else None
    if fault in ("camera_frozen", "odometry_frozen"):  # by the staleness limit, not before
        # age counts from the newest frame's capture, up to one frame period (0.1 s at 10 Hz) before the fault
        assert stale - 0.15 < res["stop_commanded_s"] < stale + BOUND_S, res
    elif fault == "robot_frozen":
        # a frozen robot cannot stop: deploy's stops time out for 2 s (exit 8, unconfirmed) and the robot is let
        # run again once deploy has left. The base's own clock stood still meanwhile; by it, the watchdog the
        # robot serves stopped the base at once (whatever libqi does with the stops queued before)
        assert summary["stop"].startswith("stop not confirmed"), res
        assert res["stop_commanded_robot_s"] < BOUND_S, res
    elif fault != "robot_killed":  # the virtual Pepper lived on: its own log shows the base stopped for good
        assert res["stop_commanded_s"] < BOUND_S and res["standstill_s"] is not None, res
    if fault in WATCHED:
        assert res["stop_commanded_s"] > 0.4, res  # by the watchdog's limit, not before
        assert any("stopMove sent" in line for line in res["watchdog"]), res
        assert any("stop confirmed" in line for line in res["watchdog"]), res
    if fault == "watchdog_stop_hangs":  # its first stop answered nothing: the watchdog sent again
        assert res["hung_stops"] == 1 and res["stop_calls"] >= 1, res
        assert any("sent again" in line for line in res["watchdog"]), res
    if fault in ("robot_killed", "camera_frozen", "odometry_frozen", "robot_frozen", "sigint", "sigterm", "sighup"):
        outcome = {"robot_killed": "connection_lost", "camera_frozen": "stale_frame", "sighup": "sigterm",
                   "odometry_frozen": "stale_odometry", "robot_frozen": "robot_not_responding"}.get(fault, fault)
        assert summary["outcome"] == outcome
    if fault == "sighup":
        assert summary["message"] == "SIGHUP"


@pytest.mark.slow
def test_the_watchdog_sends_again_until_the_base_reads_still(tmp_path):
    """Deploy killed on a robot whose first 25 stopMove calls answer 2 s late, having done nothing: the answers
    (the first 2 s after the first stop) are no confirmation; the watchdog goes on sending every 0.1 s, and the
    26th stop, sent 2.5 s after the first, stops the base."""
    res = run_fault("watchdog_stop_hangs", tmp_path, stale=6.0, hang_stops=25)
    assert res["exit_code"] == -9 and res["hung_stops"] == 25 and res["stop_calls"] >= 1, res
    assert 0.4 + 2.5 - 0.1 < res["stop_commanded_s"] < 0.5 + 2.5 + 1.0, res
    said = res["watchdog"]
    assert any("sent again" in line for line in said) and "stop confirmed" in said[-1], res


@pytest.mark.slow
def test_the_watchdog_run_beside_the_robot_stops_a_killed_deploy(tmp_path):
    """The arrangement on a real Pepper: ``python -m ssbl_pb.deploy.watchdog`` as a process of its own beside a
    robot that serves none; deploy killed, it stops the base within the bound."""
    log = tmp_path / "vp.jsonl"
    with virtual_pepper(log, 11, "default", "--no-watchdog") as (_, url):
        dog = subprocess.Popen([sys.executable, "-m", "ssbl_pb.deploy.watchdog", "--robot", url],
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert dog.stdout.readline().startswith("watchdog on "), dog.stderr.read()
            proc = start_deploy(url, tmp_path / "run", "straight", "--duration", "60", "--stale", "6")
            wait_moving(log)
            t_kill = time.time()
            proc.kill()
            proc.communicate(timeout=30)
            time.sleep(2.5)  # the stop, and the braking the watchdog waits for
        finally:
            dog.send_signal(signal.SIGTERM)
            said, _ = dog.communicate(timeout=30)
    assert dog.returncode == 143
    assert stop_times(log, t_kill)["stop_commanded_s"] < BOUND_S
    assert "heartbeats stopped" in said and "stop confirmed" in said, said


@pytest.mark.slow
def test_collision_protection_events_are_logged(tmp_path):
    """NAOqi's collision protection (imitated by the virtual Pepper) refuses moves toward a person: deploy
    logs each ALMotion/MoveFailed event in the tick that received it."""
    with virtual_pepper(tmp_path / "vp.jsonl", 35, "default", "--security-distance", "4.5") as (_, url):  # in view
        res = _deploy("--url", url, "--policy", "straight", "--duration", "5", "--quiet", "--stale", "2",
                      "--log-dir", str(tmp_path / "run"))  # (a loaded machine may deliver a frame 0.5 s late)
    assert res.returncode == 3, res.stderr  # the duration ended it
    rows = [json.loads(line) for line in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    events = [e for r in rows for e in r["events"]]
    assert events and all(e["value"][0] == "Safety" and len(e["value"][2]) == 2 for e in events)
    _, _, calls = load_log(tmp_path / "vp.jsonl")
    assert sum(c.get("call") == "MoveFailed" for c in calls) >= len(events)


def _deploy(*argv: str, timeout: float = 30) -> subprocess.CompletedProcess:
    policy = () if "--policy" in argv else ("--policy", "sffm")
    return subprocess.run([sys.executable, "-m", "ssbl_pb.deploy", *policy, "--detector", "colour", *argv],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)


def test_deploy_refuses_a_robot_without_the_watchdog_unless_told_no_watchdog(tmp_path):
    log = tmp_path / "vp.jsonl"
    with virtual_pepper(log, 35, "default", "--no-watchdog") as (vp, url):
        assert next(line for line in iter(vp.stdout.readline, "") if line.startswith("deploy: ")).rstrip().endswith(
            " --no-watchdog")  # the command it prints fits a robot without a watchdog
        res = _deploy("--url", url, "--duration", "1", "--quiet", "--log-dir", str(tmp_path / "run"))
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1, res.stderr
        assert "no SSBLWatchdog service" in lines[0] and f"python -m ssbl_pb.deploy.watchdog --robot {url}" in lines[0]
        assert "--no-watchdog" in lines[0] and not (tmp_path / "run").exists()  # nothing written
        res = _deploy("--url", url, "--duration", "1", "--quiet", "--log-dir", str(tmp_path / "run"), "--no-watchdog")
    assert res.returncode == 3 and "warning: --no-watchdog" in res.stderr, res.stderr
    assert (tmp_path / "run" / "log.jsonl").is_file()
    calls = [c["call"] for c in load_log(log)[2] if c["kind"] == "call"]
    assert calls.count("subscribeCamera") == 2 == calls.count("unsubscribe")  # the refused run released it too


def _fake_pepper(calls: list[str]) -> object:
    """A qi session serving ALMotion and ALVideoDevice with no identity: a real robot, as deploy sees it."""
    import qi

    qi.logging.setLevel(qi.logging.ERROR)

    class Motion:
        def move(self, x: float, y: float, t: float) -> None: ...
        def stopMove(self) -> None: calls.append("stopMove")  # noqa: N802, E704
        def getRobotPosition(self, s: bool) -> list[float]: return [0.0, 0.0, 0.0]  # noqa: N802
        def getRobotVelocity(self) -> list[float]: return [0.0, 0.0, 0.0]  # noqa: N802
        def getExternalCollisionProtectionEnabled(self, name: str) -> bool: return True  # noqa: N802, E704

    class Video:
        def subscribeCamera(self, name: str, cam: int, res: int, space: int, fps: int) -> str:  # noqa: N802
            calls.append("subscribeCamera")
            return name + "_0"

        def getImageRemote(self, handle: str) -> list:  # noqa: N802
            return []

        def unsubscribe(self, handle: str) -> bool:
            calls.append("unsubscribe")
            return True

    session = qi.Session()
    session.listenStandalone("tcp://127.0.0.1:0")
    session.registerService("ALMotion", Motion())
    session.registerService("ALVideoDevice", Video())
    return session


def test_no_watchdog_is_refused_for_a_real_robot(tmp_path):
    """``--no-watchdog`` is for the virtual Pepper: a robot that does not say it is one is refused with one line
    naming the fix, nothing written, its camera released; without the flag and without a watchdog, the line
    names the watchdog only."""
    calls: list[str] = []
    session = _fake_pepper(calls)
    url = session.endpoints()[0]
    try:
        res = _deploy("--url", url, "--log-dir", str(tmp_path / "out"), "--no-watchdog")
        plain = _deploy("--url", url, "--log-dir", str(tmp_path / "out"))
    finally:
        session.close()
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith("error: --no-watchdog:") and "not the virtual Pepper" in lines[0]
    assert f"python -m ssbl_pb.deploy.watchdog --robot {url}" in lines[0] and "drop --no-watchdog" in lines[0]
    lines = plain.stderr.strip().splitlines()
    assert plain.returncode == 2 and len(lines) == 1 and "no SSBLWatchdog service" in lines[0], plain.stderr
    assert "--no-watchdog" not in lines[0]  # no way round it on a real robot
    assert not (tmp_path / "out").exists()
    assert calls.count("subscribeCamera") == 2 == calls.count("unsubscribe")


def test_a_failure_in_set_up_after_connecting_leaves_no_subscription_and_no_folder(tmp_path, monkeypatch):
    """Everything after connecting (the detector, the log folder, run.json) is inside the ``try`` that closes the
    robot: a detector package missing releases the camera and leaves no log folder (nor the parents it made)."""
    from ssbl_pb.deploy import __main__ as deploy

    def missing(*args, **kwargs):
        raise ImportError("No module named 'a_detector_package'")

    monkeypatch.setattr(deploy, "Perception", missing)
    log = tmp_path / "vp.jsonl"
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGHUP)}
    switch = sys.getswitchinterval()
    try:
        with virtual_pepper(log, 35) as (_, url):
            with pytest.raises(ImportError, match="a_detector_package"):
                deploy.main(["--url", url, "--policy", "sffm", "--quiet", "--log-dir", str(tmp_path / "new" / "run")])
    finally:
        sys.setswitchinterval(switch)  # deploy's warm-up sets it for the process
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    calls = [c["call"] for c in load_log(log)[2] if c["kind"] == "call"]
    assert calls.count("subscribeCamera") == 1 == calls.count("unsubscribe"), calls
    assert not (tmp_path / "new").exists()


def test_a_port_where_nothing_speaks_qi_is_one_line_within_5_s(tmp_path):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    threading.Thread(target=lambda: server.accept(), daemon=True).start()  # accepts, then says nothing
    try:
        t0 = time.monotonic()
        res = _deploy("--robot-ip", "127.0.0.1", "--port", str(port), "--log-dir", str(tmp_path / "out"))
        took = time.monotonic() - t0
    finally:
        server.close()
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1 and "cannot connect" in lines[0], res.stderr
    assert took < 5.0 + 3.0  # the 3 s connect bound plus Python's start-up on a shared machine
    assert not (tmp_path / "out").exists()


def test_a_robot_without_the_camera_service_is_refused(tmp_path):
    import qi

    qi.logging.setLevel(qi.logging.ERROR)

    class Motion:
        def move(self, x: float, y: float, t: float) -> None: ...
        def stopMove(self) -> None: ...  # noqa: N802
        def getRobotPosition(self, s: bool) -> list[float]: return [0.0, 0.0, 0.0]  # noqa: N802
        def getRobotVelocity(self) -> list[float]: return [0.0, 0.0, 0.0]  # noqa: N802

    session = qi.Session()
    session.listenStandalone("tcp://127.0.0.1:0")
    session.registerService("ALMotion", Motion())
    try:
        res = _deploy("--url", session.endpoints()[0], "--log-dir", str(tmp_path / "out"))
    finally:
        session.close()
    assert res.returncode == 2 and "no ALVideoDevice service" in res.stderr, res.stderr
    assert not (tmp_path / "out").exists()


def test_connecting_to_nothing_raises_a_user_error():
    with pytest.raises(RobotError, match="cannot connect"):
        NaoqiRobot("tcp://127.0.0.1:1")


def test_load_log_leaves_out_a_line_still_being_written(tmp_path):
    log = tmp_path / "vp.jsonl"
    log.write_text('{"kind": "start", "wall": 0}\n{"kind": "state", "wall": 1, "cmd": [0, 0, 0]}\n{"kind": "sta')
    start, states, calls = load_log(log)
    assert start["wall"] == 0 and [s["wall"] for s in states] == [1] and calls == []
    log.write_text(log.read_text() + 'te", "wall": 2, "cmd": [0, 0, 0]}\n')  # now complete: read
    assert [s["wall"] for s in load_log(log)[1]] == [1, 2]


def test_the_benchmark_report_keeps_a_run_that_ended_on_a_fault_before_its_first_tick():
    from ssbl_pb.bench.deploy import markdown

    runs = [{"seed": 1, "outcome": "success", "true_success": True, "true_slot_m": 0.1, "true_heading_deg": 2.0,
             "true_min_clearance_m": 0.62, "tick_ms_median": 1.0, "tick_ms_p99": 3.0, "estimate_age_ms_median": 90},
            {"seed": 2, "outcome": "robot_not_responding", "true_success": False}]  # frozen before any tick
    text = markdown({"approaches": runs, "scenario": "default", "policy": "vector"})
    assert "**1/2**" in text and "smallest true clearance 0.62 m" in text
    assert "| 2 | robot_not_responding | no |" in text


@pytest.mark.slow
def test_the_command_the_virtual_pepper_prints_joins_its_group(tmp_path):
    """The README's two commands: the virtual Pepper (its people box proxies) prints the deploy command that fits
    it, and deploy with its defaults (``--detector auto``: the colour detector, since the robot says its people
    are proxies) joins the group by the simulator's ground truth."""
    import shlex

    from ssbl_pb.bench.deploy import truth_score

    log = tmp_path / "vp.jsonl"
    with virtual_pepper(log, 0, "default", "--appearance", "proxy") as (vp, url):
        lines = [vp.stdout.readline().strip() for _ in range(2)]
        command = next(line.removeprefix("deploy: ") for line in lines if line.startswith("deploy: "))
        assert command == f"python -m ssbl_pb.deploy --robot-ip 127.0.0.1 --port {url.rsplit(':', 1)[1]}"  # it
        # serves the watchdog, as a set-up Pepper does: the command needs no --no-watchdog
        argv = shlex.split(command)[1:]
        res = subprocess.run([sys.executable, *argv], capture_output=True, text=True, timeout=150, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    (run,) = (tmp_path / "runs").iterdir()  # the default --log-dir, runs/deploy-DATE-TIME
    assert json.loads((run / "run.json").read_text())["detector"] == "colour"
    score = truth_score(log, run)
    assert score["true_success"], score


def test_the_benchmark_gives_deploy_the_virtual_rooms_map(tmp_path):
    """``bench.run_approach`` reads the virtual Pepper's ``--write-map`` line: deploy's ``--map`` and
    ``--start-pose``, the room YAML written, the start pose on a free cell of its map."""
    from ssbl_pb.bench.deploy import _map_flags
    from ssbl_pb.deploy.frames import Frames, load_room

    with virtual_pepper(tmp_path / "vp.jsonl", 0, "default", "--write-map", str(tmp_path / "map")) as (vp, _):
        flags = _map_flags(vp)
    assert flags[0] == "--map" and flags[2] == "--start-pose" and len(flags) == 6
    frames = Frames(load_room(flags[1]), [float(v) for v in flags[3:5]] + [math.radians(float(flags[5]))])
    frames.check_start()  # raises on an occupied or unknown cell
    assert frames.room.room_size == (10.0, 10.0)
