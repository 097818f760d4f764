"""A virtual Pepper: ALMotion, ALVideoDevice and ALMemory served over libqi, backed by the simulated world
(``SimRobot``).

    python -m ssbl_pb.virtual --listen tcp://127.0.0.1:9559 --seed 3 --log vp.jsonl
    python -m ssbl_pb.deploy --robot-ip 127.0.0.1 --port 9559 --log-dir runs/deploy1   # as it prints

The group moves by the social force model; frames are TinyRenderer renders from CameraTop. Like a real Pepper
it keeps executing the last ``move`` until told otherwise and clamps commands to its limits. It binds loopback
addresses only unless ``--allow-remote``. Port 0 picks a free port; the first stdout line is
``listening on URL``; a later line ``deploy: python -m ssbl_pb.deploy ...`` is the command that fits it. It
identifies itself over qi (an ``SSBLVirtualPepper`` service), so deploy's ``--detector auto`` picks MoveNet for
its people (``--appearance body``, the default) or the colour detector for box proxies (``--appearance proxy``).
Like a Pepper on which the user started ``deploy.watchdog`` (docs/deploy.md), it serves the ``SSBLWatchdog``
service (the same ``Watchdog``, on its own session, ticking in a thread; its lines go to the log and stderr), so a
killed deploy leaves its base stopped; ``--no-watchdog`` serves none (deploy then refuses it unless told
``--no-watchdog`` too). ``--write-map DIR`` writes the room as a map with the flags deploy needs to use it.
``--log`` (JSONL, flushed per line) records every simulation step: time, commanded and actual velocity,
room-frame pose, odometry pose, the members, the free slot and the clearance, so tests can see when the base
really stopped. ALMemory serves the base's lasers and sonars under NAOqi's keys (``getData``, ``getListData``;
``deploy.ranges``), ray-cast in the world at their rates, the sonars only while ALSonar has a subscriber (as NAOqi
before 2.9). ALMotion reports its external collision protection on
(``getExternalCollisionProtectionEnabled``, as a Pepper's defaults; ``--collision-protection-off`` starts it off);
``--security-distance`` imitates it (a move toward a person closer than that is stopped and
``ALMotion/MoveFailed`` raised through ALMemory) while it is on. ``--walker member|stranger`` scripts a person
(``walkers``: a member stepping toward the robot's path out of view, or a stranger stepping into it). Faults to
test against: SIGUSR1
freezes the camera (frames keep their last time stamp; again to thaw), SIGUSR2 freezes odometry
(``getRobotPosition``/``getRobotVelocity`` keep answering their last values while the base moves on; again to thaw),
and ``--hang-stops N`` leaves the first N ``stopMove`` calls unanswered for 2 s, doing nothing (a lost call).
ALMotion serves calls concurrently, as NAOqi's does, and a hung call holds no thread (its answer is a future
set later): libqi's pool has about three threads here, so three sleeping calls held up every other call.
qi 3.1.5 facts this relies on: a service is hosted with ``Session().listenStandalone(url)`` and
``registerService``; every public method is exported (helpers carry ``@qi.nobind``); image bytes must be
declared (``@qi.bind("(iiiiiiriffff)", ...)``) or they arrive as their text repr.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..agents.trained import policy_groups
from ..calib.room_map import extract_room, read_map, room_yaml
from ..cli import ArgumentParser, float_in, int_at_least, run
from ..core.layouts import GROUP_MODELS
from ..deploy.naoqi import IDENTITY, import_qi
from ..deploy.robot import compose, relative
from ..deploy.watchdog import host as host_watchdog
from ..errors import UserError
from ..files import check_output_path, write_yaml
from ..params import APPEARANCES
from .camera import Camera
from .robot import SimRobot
from .services import HANG_S, PROTECTION_CHAINS, Identity, make_services
from .walkers import WALKERS, make_walker

LOOPBACK = ("127.0.0.1", "localhost", "[::1]")


def check_listen(url: str, allow_remote: bool) -> str:
    """The listen URL, refused unless ``tcp://HOST:PORT`` on a loopback host (or ``allow_remote``)."""
    host, _, port = url.removeprefix("tcp://").rpartition(":")
    if not url.startswith("tcp://") or not host or not port.isdigit() or int(port) > 65535:
        raise UserError(f"--listen {url!r}: expected tcp://HOST:PORT (port 0 picks a free one)")
    if host not in LOOPBACK and not allow_remote:
        raise UserError(f"--listen {url!r}: {host} is not a loopback address; a virtual robot answers anyone who "
                        f"reaches it, so add --allow-remote to listen there")
    return url


def state_row(robot: SimRobot, wall: float) -> dict[str, Any]:
    """A ``kind: state`` log row: the robot's ground truth (``SimRobot.truth``, room frame) at ``wall`` and its
    odometry pose (the room pose relative to the start pose)."""
    truth = robot.truth()
    return {"kind": "state", "wall": wall, **truth, "odom": relative(robot.start_pose, truth["pose"]).tolist()}


class VirtualPepper:
    """The simulation thread's state shared with the qi services (one lock: the ``SimRobot``'s)."""

    def __init__(self, robot: SimRobot, log: Path | None = None, fps_max: int = 30,
                 security_distance: float = 0.0, protection: bool = True) -> None:
        self.robot = robot
        self.security_distance = security_distance  # m; > 0: NAOqi-like collision protection (see ``protect``)
        self.protection = dict.fromkeys(PROTECTION_CHAINS, protection)  # ALMotion's external collision protection
        self.memory: Any = None  # the ALMemory service, for ALMotion/MoveFailed
        self.sonar_subscribers: set[str] = set()  # ALSonar's: the sonars run while any (``services.make_services``)
        self.sonar_held: dict[str, float] = {}  # ... and ALMemory holds their last echo meanwhile
        self._refused = False
        self.epoch = time.time()  # the robot clock of frame stamps: wall time at start + sim time
        self.frozen = False
        self.odometry_frozen: tuple[list[float], list[float]] | None = None  # (pose, velocity) answered while frozen
        self.hang_stops = 0  # stopMove calls still to leave unanswered (``--hang-stops``)
        self.fps = 0
        self.subs: dict[str, tuple[int, int]] = {}  # handle -> (resolution, colour space)
        self.fps_max = fps_max
        self._log = open(log, "a", buffering=1) if log is not None else None  # closed in close()
        self._log_lock = threading.Lock()
        self.camera: Camera | None = None  # started by ``run``
        self.write({"kind": "start", "wall": time.time(), "start_pose": robot.start_pose.tolist(), **robot.info})

    def write(self, row: dict[str, Any]) -> None:
        if self._log is not None:
            with self._log_lock:
                self._log.write(json.dumps(row) + "\n")

    def watchdog_line(self, line: str) -> None:
        """A line of the hosted watchdog: a ``kind: watchdog`` log row, and stderr (never blocking the watchdog
        on a full pipe: whoever starts the virtual Pepper reads its stdout only up to the deploy line)."""
        self.write({"kind": "watchdog", "wall": time.time(), "t": self.robot.t, "line": line})
        try:
            print(f"watchdog: {line}", file=sys.stderr, flush=True)
        except (OSError, ValueError):
            pass

    def step_row(self) -> None:
        self.write(state_row(self.robot, time.time()))

    def run(self, stop: threading.Event) -> None:
        """Advance the world in real time (and render the camera at the subscribed rate) until ``stop``."""
        dt = self.robot.world.params.dt
        self.camera = Camera(self.robot)
        t0 = time.monotonic()
        next_frame = 0.0
        while not stop.is_set():
            behind = time.monotonic() - t0 - self.robot.t
            if behind > 1.0:  # stopped (SIGSTOP) or starved: do not replay the gap, jump it
                self.write({"kind": "time_jump", "wall": time.time(), "t": self.robot.t, "skipped": behind})
                t0 += behind
            if behind < dt:
                time.sleep(dt - behind)
                continue
            self.robot.advance(dt)
            self.protect()
            self.step_row()
            if self.fps and not self.frozen and self.robot.t >= next_frame:
                self.camera.request()
                next_frame = self.robot.t + 1.0 / self.fps - 1e-6

    def protect(self) -> None:
        """NAOqi's external collision protection, simplified: a move heading toward a person whose clearance is
        below ``security_distance`` is stopped and ``ALMotion/MoveFailed`` raised (once per move)."""
        r = self.robot
        if self.security_distance <= 0 or not self.protection["Move"] or not any(r._cmd[:2]) or self._refused:
            return
        w = r.world
        clear = w.human_clearance()
        k = int(np.argmin(clear))
        rel = relative(w.robot_pose, np.array([*w.group.pos[k], 0.0]))[:2]  # the person in the robot frame
        if clear[k] < self.security_distance and float(r._cmd[:2] @ rel) > 0:
            r.stop()
            self._refused = True
            self.write({"kind": "call", "wall": time.time(), "t": r.t, "call": "MoveFailed", "obstacle": rel.tolist()})
            if self.memory is not None:
                self.memory.raise_event("ALMotion/MoveFailed", ["Safety", 1, [float(rel[0]), float(rel[1])]])

    def toggle_odometry_freeze(self) -> None:
        """Freeze odometry at its current reading (or thaw it): ALMotion answers the frozen values."""
        odo = self.robot.odometry()
        self.odometry_frozen = None if self.odometry_frozen else (odo.pose.tolist(), odo.velocity.tolist())
        self.write({"kind": "call", "wall": time.time(), "t": self.robot.t,
                    "call": "odometry_frozen" if self.odometry_frozen else "odometry_thawed"})

    def close(self) -> None:
        if self.camera is not None:
            self.camera.close()
        self.robot.close()
        if self._log is not None:
            with self._log_lock:
                self._log.close()
            self._log = None


def write_room_map(folder: Path, robot: SimRobot, resolution: float = 0.05,
                   centre: tuple[float, float] = (2.0, 1.0)) -> tuple[Path, np.ndarray]:
    """The simulated room as a ROS map (``map.pgm``, ``map.yaml``) and its room YAML (``room.yaml``, as
    ``tools/import_map.py`` makes it), the room's centre at ``centre`` on the map (so the frames differ); returns
    the room YAML and the robot's start pose on the map (x, y, yaw)."""
    sx, sy = robot.world.params.room_size
    wall = robot.world.params.wall_thickness
    margin = 1.0 + wall
    w, h = (int(round((v + 2 * margin) / resolution)) for v in (sx, sy))
    img = np.full((h, w), 205, np.uint8)  # unknown outside
    m, k = int(round(1.0 / resolution)), int(round(wall / resolution))
    img[m:h - m, m:w - m] = 0  # walls ...
    img[m + k:h - m - k, m + k:w - m - k] = 254  # ... around the free room
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / "map.pgm"), img)
    origin = (centre[0] - (sx / 2 + margin), centre[1] - (sy / 2 + margin), 0.0)
    (folder / "map.yaml").write_text(f"image: map.pgm\nresolution: {resolution}\norigin: {list(origin)}\n"
                                     "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    grid = read_map(folder / "map.yaml")
    data = room_yaml(grid, extract_room(grid, seed=centre), centre)
    write_yaml(folder / "room.yaml", data, header="the virtual Pepper's room (python -m ssbl_pb.virtual)")
    t = data["map_to_room"]
    start = compose(np.array([t["x"], t["y"], t["yaw"]]), robot.start_pose)
    return folder / "room.yaml", start


def deploy_command(url: str, groups: str | None = None, on_map: tuple[Path, np.ndarray] | None = None,
                   watchdog: bool = True) -> str:
    """The deploy command line that fits a virtual Pepper listening on ``url`` (``watchdog``: it serves one)."""
    address, _, port = url.removeprefix("tcp://").rpartition(":")
    cmd = f"python -m ssbl_pb.deploy --robot-ip {address} --port {port}"
    if not watchdog:
        cmd += " --no-watchdog"
    if groups is not None:
        cmd += f" --groups {groups}"
    if on_map is not None:
        (mx, my, myaw) = on_map[1]
        cmd += f" --map {on_map[0]} --start-pose {mx:.3f} {my:.3f} {math.degrees(myaw):.2f}"
    return cmd


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog="python -m ssbl_pb.virtual", description=__doc__)
    ap.add_argument("--listen", default="tcp://127.0.0.1:9559", help="tcp://HOST:PORT (default %(default)s)")
    ap.add_argument("--seed", type=int_at_least(0), default=0, help="episode seed of the simulated scene (default 0)")
    ap.add_argument("--scenario", default="default", help="default | mixed | FORMATION[-N] | ... (as evaluate)")
    ap.add_argument("--groups", choices=GROUP_MODELS, help="how the group stands: calibrated (real groups' size) "
                    "or paper (1.0 m circles); default: the one the shipped policy was trained on")
    ap.add_argument("--log", type=Path, help="JSONL log of every simulation step")
    ap.add_argument("--allow-remote", action="store_true", help="allow a non-loopback --listen address")
    ap.add_argument("--duration", type=float_in(0.0, 86400.0), default=0.0,
                    help="exit after this many seconds (0: run until killed)")
    ap.add_argument("--security-distance", type=float_in(0.0, 5.0), default=0.0,
                    help="m; > 0 stops moves toward a person closer than this and raises ALMotion/MoveFailed, like "
                    "NAOqi's collision protection (default 0: off)")
    ap.add_argument("--collision-protection-off", action="store_true", help="start with ALMotion's external "
                    "collision protection off (getExternalCollisionProtectionEnabled answers false), as a robot "
                    "someone turned it off on")
    ap.add_argument("--walker", choices=WALKERS, help="script a person: a member who walks 0.5 m toward the "
                    "robot's path while out of its camera's view, or a stranger (never seen) who steps into it")
    ap.add_argument("--hang-stops", type=int_at_least(0), default=0, metavar="N",
                    help=f"leave the first N stopMove calls unanswered for {HANG_S:g} s, doing nothing (a lost "
                    "call, to test the watchdog; default 0)")
    ap.add_argument("--appearance", choices=APPEARANCES, default="body", help="how the people look: body (made "
                    "from a body model; deploy's --detector auto then picks movenet; default) or proxy (boxes for "
                    "the colour detector)")
    ap.add_argument("--no-watchdog", action="store_true", help="serve no SSBLWatchdog (a robot on which the "
                    "watchdog was not started: deploy refuses it unless given --no-watchdog)")
    ap.add_argument("--write-map", type=Path, metavar="DIR", help="write the room as a map (DIR/room.yaml for "
                    "deploy's --map) and print the robot's --start-pose on it")
    args = ap.parse_args(argv)
    url = check_listen(args.listen, args.allow_remote)
    for path, flag, is_dir in ((args.log, "--log", False), (args.write_map, "--write-map", True)):
        if path is not None:
            check_output_path(path, flag, is_dir=is_dir)
    qi = import_qi()
    groups = args.groups
    if groups is None:
        groups = policy_groups("vector")
    robot = SimRobot(args.scenario, args.seed, groups=groups, appearance=args.appearance)
    if args.walker is not None:
        robot.add_walker(make_walker(args.walker))
    session = qi.Session()
    try:
        session.listenStandalone(url)
    except RuntimeError as exc:
        robot.close()
        reason = str(exc).split("[")[0].strip().splitlines()[-1]  # libqi appends its source path in brackets
        raise UserError(f"--listen {url}: cannot listen there ({reason})") from None
    try:  # listening first: a port in use must not leave a map behind
        on_map = write_room_map(args.write_map, robot) if args.write_map is not None else None
    except BaseException:
        session.close()
        robot.close()
        raise
    vp = VirtualPepper(robot, args.log, security_distance=args.security_distance,
                       protection=not args.collision_protection_off)
    vp.hang_stops = args.hang_stops
    for name, service in zip(("ALMotion", "ALVideoDevice", "ALMemory", "ALSonar"), make_services(vp), strict=True):
        session.registerService(name, service)
    session.registerService(IDENTITY, Identity({**robot.identity, "scenario": args.scenario,
                                                "seed": str(args.seed), "groups": groups}, vp))
    watching = None if args.no_watchdog else host_watchdog(session, say=vp.watchdog_line)[1]
    signal.signal(signal.SIGUSR1, lambda *_: setattr(vp, "frozen", not vp.frozen))
    signal.signal(signal.SIGUSR2, lambda *_: vp.toggle_odometry_freeze())
    x, y, yaw = robot.start_pose
    endpoint = session.endpoints()[0]
    print(f"listening on {endpoint}", flush=True)
    print(f"scene: seed {args.seed}, {robot.info['formation']} group of {robot.info['n_humans']} ({groups}), "
          f"robot at ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f} deg) in the room frame", flush=True)
    if on_map is not None:
        (mx, my, myaw) = on_map[1]
        print(f"map: --map {on_map[0]} --start-pose {mx:.3f} {my:.3f} {math.degrees(myaw):.2f}", flush=True)
    print(f"deploy: {deploy_command(endpoint, args.groups, on_map, watching is not None)}", flush=True)
    stop = threading.Event()
    if args.duration > 0:
        threading.Timer(args.duration, stop.set).start()
    try:
        vp.run(stop)
    finally:
        stop.set()
        if watching is not None:
            watching.set()
        session.close()
        vp.close()
    return 0


def load_log(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]], list[dict[str, Any]]]:
    """A virtual Pepper log: its start row, its state rows and its other rows (calls, time jumps); a last line
    still being written is left out."""
    text = Path(path).read_text()
    lines = text.splitlines() if text.endswith("\n") else text.splitlines()[:-1]
    rows = [json.loads(line) for line in lines if line.strip()]
    start = next(r for r in rows if r["kind"] == "start")
    return start, [r for r in rows if r["kind"] == "state"], [r for r in rows if r["kind"] not in ("start", "state")]


if __name__ == "__main__":
    run(main)
