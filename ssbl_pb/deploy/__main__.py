"""Run the learned approach on a Pepper over NAOqi, safely: camera -> people -> policy -> base, with a log.

    python -m ssbl_pb.deploy --robot-ip 192.168.1.20 --policy vector --log-dir runs/deploy1        # NAOqi 2.5
    python -m ssbl_pb.deploy --url tcps://192.168.1.20:9503 --user nao --token PASS ...           # NAOqi 2.9
    python -m ssbl_pb.deploy --robot-ip 127.0.0.1 --port 9559 --log-dir runs/vp               # the virtual Pepper
    python -m ssbl_pb.deploy ... --map room.yaml --start-pose 3.2 1.5 90   # paths on the map, the real walls

Ends on success (joined the group), on --duration, or on a fault; the base is stopped first in every case and the
exit code says which (0 success, 1 a bug, 2 bad input, 3 duration, 4 person too close, 5 stale frame, 6 stale
odometry, 7 connection lost, 8 robot not responding, 130 Ctrl-C, 143 SIGTERM or SIGHUP; docs/deploy.md). DIR
gets log.jsonl (one line per tick), run.json, summary.json and paths.png. Start ``python -m ssbl_pb.deploy.watchdog``
beside the robot first, so the base stops even if this process dies: deploy refuses to start without it (the
virtual Pepper serves one itself; ``--no-watchdog`` is accepted for the virtual Pepper only).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import shutil
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..agents.trained import policy_groups, policy_view, resolve_model
from ..cli import ArgumentParser, run_without_teardown
from ..core import observation as ob
from ..core.layouts import GROUP_MODELS
from ..core.task import TaskParams
from ..env.gymenv.approach import core_kwargs
from ..errors import Terminated, UserError
from ..files import check_output_path
from ..params import RobotParams, SocialParams, WorldParams, from_dict
from ..perception.camera import PinholeCamera
from .frames import Frames, load_room
from .log import LOG, RunLog, write_run, write_summary
from .loop import DeployLoop, DeployParams, Setup, status_printer
from .naoqi import NaoqiRobot, check_watchdog, robot_url
from .perceive import DETECTORS, Perception, detector_for
from .plot import draw
from .policy import BASELINES, load_policy


def _parser() -> argparse.ArgumentParser:
    ap = ArgumentParser(prog="python -m ssbl_pb.deploy", description=__doc__)
    ap.add_argument("--robot-ip", help="the robot's address (NAOqi 2.5: tcp://IP:PORT)")
    ap.add_argument("--port", type=int, default=9559, help="NAOqi port (default 9559)")
    ap.add_argument("--url", help="full qi URL instead, e.g. tcps://IP:9503 for NAOqi 2.9 (with --user/--token)")
    ap.add_argument("--user", help="NAOqi 2.9 login user (default nao)")
    ap.add_argument("--token", help="NAOqi 2.9 login password/token")
    ap.add_argument("--policy", default="vector", help="vector (shipped) | run dir | .zip | sffm | straight | random")
    ap.add_argument("--detector", default="auto", help="auto (default: what the virtual Pepper says over qi, "
                    "movenet for its bodies or colour for its box proxies; movenet on a real robot) | movenet (real "
                    "people, whole or cut above the feet: MoveNet MultiPose, see docs/tracking.md) | hog (real "
                    "people, whole bodies) | ssd (the learned SSDLite pedestrian detector) | colour (the virtual "
                    "Pepper's box proxies)")
    ap.add_argument("--camera-yaml", help="calibrated camera (tools/calibrate_camera.py); default nominal CameraTop")
    ap.add_argument("--robot-yaml", help="identified base dynamics (tools/identify_dynamics.py)")
    ap.add_argument("--social-yaml", help="calibrated group parameters (tools/calibrate_humans.py)")
    ap.add_argument("--groups", choices=GROUP_MODELS, help="the group model the policy sees: calibrated (real "
                    "groups' size) or paper (1.0 m circles); default: the one the policy was trained on (its "
                    "config's env.groups; baselines: calibrated)")
    ap.add_argument("--map", help="room YAML from tools/import_map.py: real walls for the policy, paths on the map")
    ap.add_argument("--start-pose", type=float, nargs=3, metavar=("X", "Y", "YAW"),
                    help="with --map: the robot's start pose on the map (metres, degrees)")
    ap.add_argument("--log-dir", type=Path, help="output folder (default runs/deploy-DATE-TIME)")
    ap.add_argument("--max-speed", type=float, default=DeployParams.max_speed,
                    help="m/s clamp on the base speed (default %(default)g)")
    ap.add_argument("--rate", type=float, help="control rate in Hz (default: the policy's own, 10 Hz for every "
                    "shipped one; a learned policy runs only at the rate it was trained at, since its action "
                    "smoothing and shield assume that period)")
    ap.add_argument("--duration", type=float, default=DeployParams.duration_s,
                    help="give up after this many seconds (default %(default)g)")
    ap.add_argument("--stop-distance", type=float, default=DeployParams.stop_distance,
                    help="stop when a tracked person is this close to the footprint (m, default %(default)g)")
    ap.add_argument("--stale", type=float, default=DeployParams.stale_s,
                    help="stop when frame or odometry is older (s, default %(default)g)")
    ap.add_argument("--continue-after-success", action="store_true", help="hold the slot until --duration")
    ap.add_argument("--no-watchdog", action="store_true",
                    help="the virtual Pepper only: run without its watchdog (default: refuse a robot without the "
                         "SSBLWatchdog service, since NAOqi keeps the base's last command if this process dies; on "
                         "a real robot start python -m ssbl_pb.deploy.watchdog beside it)")
    ap.add_argument("--allow-collision-protection-off", action="store_true",
                    help="run even when NAOqi's external collision protection for the base is off (default: refuse; "
                         'turn it on with ALMotion.setExternalCollisionProtectionEnabled("Move", True))')
    ap.add_argument("--quiet", action="store_true", help="no status line")
    return ap


def _number(flag: str, value: float, lo: float, hi: float, unit: str) -> None:
    if not (math.isfinite(value) and lo < value <= hi):
        raise UserError(f"{flag} {value:g}: expected a number in ({lo:g}, {hi:g}] {unit}")


def _params(args: argparse.Namespace) -> Any:
    """Every input checked before anything connects or is written: (params, robot, social, task, policy, frames)."""
    _number("--max-speed", args.max_speed, 0.0, 0.55, "m/s (Pepper's hardware max is 0.55)")
    args.rate = _rate(args.policy, args.rate)
    _number("--duration", args.duration, 0.0, 86400.0, "s")
    _number("--stop-distance", args.stop_distance, 0.0, 3.0, "m")
    _number("--stale", args.stale, 0.0, 10.0, "s")
    if args.detector not in ("auto", *DETECTORS):
        raise UserError(f"--detector {args.detector!r}: expected one of {['auto', *DETECTORS]}")
    if args.start_pose is not None and args.map is None:
        raise UserError("--start-pose is a pose on a map: give --map room.yaml too")
    if args.start_pose is not None and not all(math.isfinite(v) for v in args.start_pose):
        raise UserError(f"--start-pose {' '.join(f'{v:g}' for v in args.start_pose)}: expected three finite "
                        f"numbers X Y YAW (metres, degrees)")
    kwargs, _ = core_kwargs(camera_yaml=args.camera_yaml, robot_yaml=args.robot_yaml, social_yaml=args.social_yaml)
    robot = from_dict(RobotParams, kwargs.get("robot"), "robot")
    social = from_dict(SocialParams, kwargs.get("social"), "social")
    task = TaskParams()
    params = DeployParams(rate_hz=args.rate, max_speed=args.max_speed, stale_s=args.stale,
                          stop_distance=args.stop_distance, duration_s=args.duration,
                          continue_after_success=args.continue_after_success, status_s=0.0 if args.quiet else 1.0)
    start = None
    if args.start_pose is not None:
        x, y, yaw = args.start_pose
        start = np.array([x, y, math.radians(yaw)])
    frames = Frames(load_room(args.map) if args.map else None, start)
    frames.check_start()
    policy = load_policy(args.policy, robot, social, task, params.stop_distance)
    policy_view(args.policy)  # the observation it was trained on can be built here, checked before connecting
    if args.groups is None:
        args.groups = policy_groups(args.policy)
    return params, robot, social, task, policy, frames


def _rate(spec: str, rate: float | None) -> float:
    """The control rate: ``--rate`` checked, by default the policy's own (its config's ``env.world.dt``). A learned
    policy is refused any other: its action smoothing (alpha per step) and its shield (``control_period``) are
    those of its training period, and so is what it learned; baselines run at any rate up to 50 Hz."""
    trained = None
    if spec not in BASELINES:
        world = (resolve_model(spec)[2].get("env") or {}).get("world") or {}
        trained = 1.0 / float(world.get("dt", WorldParams.dt)) if isinstance(world, dict) else None
    if rate is None:
        return trained or 1.0 / WorldParams.dt
    _number("--rate", rate, 0.0, 50.0, "Hz")
    if trained is not None and abs(rate - trained) > 1e-6:
        raise UserError(f"--rate {rate:g}: the policy {spec!r} was trained at {trained:g} Hz (its action smoothing "
                        f"and shield assume that period); leave --rate out or give {trained:g}")
    return rate


def _warm_up(policy: Any) -> None:
    """One prediction before the robot moves: torch's first call took 0.3 s (measured on the virtual Pepper: the
    first approach ticks took 306, 140 and 79 ms without it). Also one torch thread (a small MLP; more only
    contend with detection) and a 1 ms GIL switch interval, so the control thread gets the interpreter back
    within ~1 ms of each robot call while the detector thread runs Python (5 ms by default)."""
    sys.setswitchinterval(0.001)
    if hasattr(policy, "model"):  # a trained model (baselines need no torch)
        import torch

        torch.set_num_threads(1)
    policy.predict(np.zeros(ob.OBS_SIZE, dtype=np.float32), state=None, episode_start=np.ones(1, dtype=bool),
                   deterministic=True)
    if hasattr(policy, "reset"):
        policy.reset()


def _hang_up(signum: int, frame: Any) -> None:
    raise Terminated("SIGHUP")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        # Ctrl-C must stop the robot even when this process inherited SIGINT ignored (started in the background
        # by a shell or a supervisor: measured, a background-started deploy kept driving through a SIGINT)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        # the ssh connection to this machine dropping stops the run, as SIGTERM, even under nohup (cli.run leaves
        # an ignored SIGHUP ignored): a run nobody watches must not go on driving (tmux or screen outlive a drop)
        signal.signal(signal.SIGHUP, _hang_up)
    url = robot_url(args.robot_ip, args.port, args.url)
    folder = args.log_dir or Path("runs") / time.strftime("deploy-%Y%m%d-%H%M%S")
    check_output_path(folder, "--log-dir")
    if (folder / LOG).exists():
        raise UserError(f"--log-dir {folder}: already holds a deploy log; choose a new folder")
    params, robot_params, social, task, policy, frames = _params(args)
    _warm_up(policy)
    limits = dataclasses.replace(robot_params, max_speed=params.max_speed)
    robot = NaoqiRobot(url, limits, user=args.user, token=args.token,
                       allow_protection_off=args.allow_collision_protection_off)
    try:  # from here on every way out closes the robot (the loop closes it too; close runs once)
        return _run(args, url, folder, robot, params, robot_params, social, task, policy, frames)
    finally:
        robot.close()


def _new_folders(folder: Path) -> Path | None:
    """The outermost of ``folder`` and its parents that does not exist yet (what making it would create)."""
    top = None
    while not folder.exists():
        top, folder = folder, folder.parent
    return top


def _run(args: argparse.Namespace, url: str, folder: Path, robot: Any, params: Any, robot_params: Any, social: Any,
         task: Any, policy: Any, frames: Any) -> int:
    made = _new_folders(folder)
    try:  # set-up: a failure here leaves no folder behind (and main closes the robot)
        warning = check_watchdog(robot, url, args.no_watchdog)
        camera = PinholeCamera.from_yaml(args.camera_yaml) if args.camera_yaml else None
        args.detector = detector_for(args.detector, robot)
        perception = Perception(robot, time.monotonic, args.detector, robot_params, camera, social=social)
        folder.mkdir(parents=True, exist_ok=True)
        write_run(folder, {"url": url, "policy": args.policy, "groups": args.groups,
                           "detector": args.detector, "map": args.map, "deploy": dataclasses.asdict(params),
                           "robot": dataclasses.asdict(robot_params), "watchdog": robot.watchdog is not None,
                           "started": time.strftime("%Y-%m-%d %H:%M:%S"), **frames.info()})
        log = RunLog(folder)
        loop = DeployLoop(Setup(robot, policy, perception, frames, robot_params, social, task, args.groups,
                                **dataclasses.asdict(policy_view(args.policy))),
                          params, log, status=None if args.quiet else status_printer())
    except BaseException:
        if made is not None:
            shutil.rmtree(made, ignore_errors=True)
        raise
    if warning:
        _tell(warning)
    try:
        outcome, message = loop.run()
    finally:
        _finish(folder, log, loop, frames, perception)
    stop = f"; {loop.stop_note}" if loop.stop_note else "; base stopped"
    if outcome == "success":
        _tell(f"success: {message} -> {folder}", sys.stdout)
    else:
        _tell(f"stopped ({outcome}): {message}{stop} -> {folder}")
    return loop.exit_code


def _finish(folder: Path, log: Any, loop: Any, frames: Any, perception: Any) -> None:
    """The summary and the paths' figure, once the base is stopped; neither may change how the run ended."""
    log.close()
    extra = {"stop": loop.stop_note or "stopMove answered", **frames.info(), "perception": perception.info()}
    if loop.shutdown_error:
        extra["shutdown_error"] = loop.shutdown_error
    write_summary(folder, log.summary(loop.outcome, loop.exit_code, loop.message, extra))
    if loop.outcome != "exception":
        try:
            draw(folder)
        except Exception as exc:  # noqa: BLE001 - a figure must not turn a fault's exit code into a bug's
            _tell(f"warning: paths.png not drawn ({type(exc).__name__}: {exc})")


def _tell(line: str, stream: Any = None) -> None:
    """A report line; a terminal gone (SIGHUP: the ssh connection dropped) must not change the exit code."""
    try:
        print(line, file=stream or sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    run_without_teardown(main)
