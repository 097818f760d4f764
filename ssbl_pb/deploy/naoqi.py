"""Pepper over NAOqi: the ``Robot`` interface on ALMotion, ALVideoDevice and ALMemory (the only client module
importing qi).

Every qi call is bounded (``_async=True`` + ``Future.value(timeout_ms)``): a frozen peer would otherwise block
forever. Connecting is bounded too (a silent host otherwise takes minutes). ``session.disconnected`` fires
within milliseconds when the robot process dies; from then on every call raises ``ConnectionLost``.
NAOqi 2.5 speaks ``tcp://IP:9559``; 2.9 ``tcps://IP:9503`` with a login (user, token). The camera
subscription is released on every exit (NAOqi allows 6 subscriptions per name). A ``SSBLWatchdog`` service
(``deploy.watchdog``) registered on the robot gets a heartbeat with every command. The base's lasers and sonars
are read from ALMemory (``ranges``: one ``getListData`` of ``ranges.KEYS``). Connecting refuses a robot whose
external collision protection for the base (``ALMotion.getExternalCollisionProtectionEnabled("Move")``) is off,
unless told ``allow_protection_off``.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import numpy as np

from ..core.range_sensors import RANGES
from ..errors import UserError
from ..params import RobotParams
from .faults import ConnectionLost, RobotNotResponding
from .ranges import KEYS, scan_points
from .robot import Frame, Odometry, RangeScan, clamp_command

MOTION = ("move", "stopMove", "getRobotPosition", "getRobotVelocity")
VIDEO = ("subscribeCamera", "getImageRemote", "unsubscribe")
WATCHDOG = "SSBLWatchdog"
SONAR_SUBSCRIBER = "ssbl_pb"  # the name deploy subscribes ALSonar under
IDENTITY = "SSBLVirtualPepper"  # served by ``virtual.pepper``: a simulated Pepper says so (and which detector fits)
RESOLUTIONS = {0: (160, 120), 1: (320, 240), 2: (640, 480)}  # NAOqi kQQVGA, kQVGA, kVGA
RGB, BGR = 11, 13  # NAOqi colour spaces


class RobotError(UserError):
    """The robot cannot be used (unreachable, missing services, asleep); nothing has moved."""


def import_qi() -> Any:
    """The ``qi`` module with its console logging limited to errors, or a ``UserError`` saying how to get it."""
    try:
        import qi
    except ImportError as exc:
        raise RobotError("talking to a Pepper needs the 'qi' package (NAOqi's libqi, >= 3.1.5): "
                         "pip install 'ssbl-pb[robot]'") from exc
    qi.logging.setLevel(qi.logging.ERROR)  # its warnings (no qi.Application, ...) would break one-line errors
    return qi


def robot_url(ip: str | None, port: int = 9559, url: str | None = None) -> str:
    """The qi URL from ``--robot-ip``/``--port`` or ``--url`` (tcp:// for NAOqi 2.5, tcps:// for 2.9)."""
    if url:
        if not url.startswith(("tcp://", "tcps://")) or url.count(":") != 2:
            raise UserError(f"--url {url!r}: expected tcp://HOST:PORT (NAOqi 2.5) or tcps://HOST:PORT (2.9)")
        return url
    if not ip:
        raise UserError("give --robot-ip IP (NAOqi 2.5, port 9559) or --url tcps://IP:9503 (NAOqi 2.9)")
    if not (isinstance(port, int) and 0 < port < 65536):
        raise UserError(f"--port {port!r}: expected an integer in 1..65535")
    return f"tcp://{ip}:{port}"


@dataclasses.dataclass(frozen=True)
class NaoqiParams:
    """Timeouts and the camera subscription (ours: a loopback call costs ~0.3 ms, a Pepper on Wi-Fi ~5-30 ms)."""

    connect_timeout_s: float = 3.0  # the issue allows 5 s for a clear 'unreachable' line
    call_timeout_s: float = 0.3  # odometry / move / stopMove; a frozen robot is noticed within one tick + this
    stop_retry_s: float = 2.0  # s deploy's own stop keeps trying (each try call_timeout_s): a stall shorter than
    #   this still gets a stop through; longer, the watchdog on the robot stops the base
    frame_timeout_s: float = 0.5  # a QVGA frame round trip (~1 ms on loopback)
    camera: int = 0  # CameraTop
    resolution: int = 1  # kQVGA 320x240
    colour_space: int = RGB
    fps: int = 15  # > the 10 Hz control rate, so the estimate is at most ~70 ms old when detection keeps up
    subscriber: str = "ssbl_deploy"


class _Authenticator:
    """libqi's client login for NAOqi 2.9 (``tcps://``): it asks for ``initialAuthData`` (user, token)."""

    def __init__(self, user: str, token: str) -> None:
        self.user, self.token = user, token

    def initialAuthData(self) -> dict[str, str]:
        return {"user": self.user, "token": self.token}

    def _processAuth(self, data: Any) -> dict[str, str]:
        return {}

    def newAuthenticator(self) -> _Authenticator:  # the factory: one object serves both
        return self


class NaoqiRobot:
    """A Pepper (or the virtual Pepper) over qi; connects, checks services and subscribes the camera."""

    def __init__(self, url: str, limits: RobotParams | None = None, params: NaoqiParams | None = None,
                 user: str | None = None, token: str | None = None, allow_protection_off: bool = False) -> None:
        qi = import_qi()
        self.url, self.limits, self.p = url, limits or RobotParams(), params or NaoqiParams()
        self.lost = threading.Event()
        self.unresponsive = False  # a bounded call timed out (until a stop is answered): close() tries nothing more
        self.stopped = False  # a stopMove answered since the last move
        self.closed = False
        self.handle: str | None = None
        self.watchdog: Any = None
        self.identity: dict[str, str] | None = None  # a virtual Pepper's ``describe()``; None for a real robot
        self.move_failed: list[dict[str, Any]] = []
        self.memory: Any = None  # ALMemory where it holds the base's range sensors' keys (``ranges``)
        self.sonar: Any = None  # ALSonar, subscribed while deploy runs (NAOqi before 2.9 has it)
        self.protection: bool | None = None  # external collision protection for the base; None: cannot tell
        self._subscribers: list[Any] = []
        self.session = qi.Session()
        if user is not None or token is not None:
            self.session.setClientAuthenticatorFactory(_Authenticator(user or "nao", token or ""))
        try:
            self.session.connect(url, _async=True).value(int(self.p.connect_timeout_s * 1000))
        except RuntimeError as exc:
            raise RobotError(f"cannot connect to {url} within {self.p.connect_timeout_s:g} s ({exc}): is NAOqi "
                             f"running there? (NAOqi 2.5: tcp://IP:9559; 2.9: tcps://IP:9503 with --user and "
                             f"--token)") from None
        self.session.disconnected.connect(lambda *_: self.lost.set())
        try:
            self.motion = self._service("ALMotion", MOTION)
            self.video = self._service("ALVideoDevice", VIDEO)
            self._optional_services()
            self._check_protection(allow_protection_off)
            p = self.p
            self.handle = str(self._call(self.video.subscribeCamera(p.subscriber, p.camera, p.resolution,
                                                                    p.colour_space, p.fps, _async=True),
                                         "ALVideoDevice.subscribeCamera", p.frame_timeout_s))
        except BaseException:
            self.close()
            raise

    # -- setup -----------------------------------------------------------------------------------------------
    def _service(self, name: str, methods: tuple[str, ...]) -> Any:
        try:
            svc = self.session.service(name, _async=True).value(int(self.p.connect_timeout_s * 1000))
        except RuntimeError as exc:
            raise RobotError(f"{self.url}: no {name} service ({exc}); a Pepper running NAOqi has it") from None
        missing = [m for m in methods if not hasattr(svc, m)]
        if missing:
            raise RobotError(f"{self.url}: {name} lacks {missing}; deploy needs {list(methods)}")
        return svc

    def _optional_services(self) -> None:
        """The watchdog (heartbeats) and ALMemory's ALMotion/MoveFailed events, where the robot has them."""
        names = {s["name"] for s in self._call(self.session.services(_async=True), "services")}
        if WATCHDOG in names:
            self.watchdog = self._service(WATCHDOG, ("heartbeat", "disarm"))
        if IDENTITY in names:
            facts = self._call(self._service(IDENTITY, ("describe",)).describe(_async=True), f"{IDENTITY}.describe")
            self.identity = {str(k): str(v) for k, v in dict(facts).items()}
        if "ALMemory" in names:
            memory = self.session.service("ALMemory", _async=True).value(int(self.p.connect_timeout_s * 1000))
            sub = self._call(memory.subscriber("ALMotion/MoveFailed", _async=True), "ALMemory.subscriber")
            sub.signal.connect(lambda value: self.move_failed.append({"t": time.monotonic(), "value": value}))
            self._subscribers.append(sub)
            try:  # the base's lasers and sonars, where the robot publishes them (a Pepper does)
                self._call(memory.getListData(list(KEYS), _async=True), "ALMemory.getListData")
                self.memory = memory
            except RuntimeError:  # no such keys: no range readings
                pass
        if self.memory is not None and "ALSonar" in names:  # NAOqi before 2.9 runs the sonars only for subscribers
            # (naoqi_driver's converters/sonar.cpp subscribes before it reads their keys): without, ALMemory holds
            # an old echo and the guards would brake for what stood there, or not for what stands there now
            sonar = self._service("ALSonar", ("subscribe", "unsubscribe"))
            self._call(sonar.subscribe(SONAR_SUBSCRIBER, _async=True), "ALSonar.subscribe")
            self.sonar = sonar
        if hasattr(self.motion, "robotIsWakeUp") and not self._call(self.motion.robotIsWakeUp(_async=True),
                                                                    "ALMotion.robotIsWakeUp"):
            raise RobotError(f"{self.url}: the robot is resting (ALMotion.robotIsWakeUp() is false); wake it up "
                             "(ALMotion.wakeUp, or press the chest button) and run again")

    def _check_protection(self, allow_off: bool) -> None:
        """``RobotError`` (one line: what is off, the fix) when NAOqi's external collision protection for the base
        is off or cannot be checked, unless ``allow_off``."""
        what = 'ALMotion.getExternalCollisionProtectionEnabled("Move")'
        if hasattr(self.motion, "getExternalCollisionProtectionEnabled"):
            self.protection = bool(self._call(self.motion.getExternalCollisionProtectionEnabled("Move", _async=True),
                                              what))
        if not self.protection and not allow_off:
            state = "is off" if self.protection is False else "cannot be checked (ALMotion lacks it)"
            raise RobotError(f"{self.url}: NAOqi's external collision protection for the base ({what}) {state}: turn "
                             f'it on with ALMotion.setExternalCollisionProtectionEnabled("Move", True), or pass '
                             f"--allow-collision-protection-off")

    def _call(self, future: Any, what: str, timeout_s: float | None = None) -> Any:
        """Wait for a qi future at most ``timeout_s``; timeouts and lost connections become faults."""
        timeout = self.p.call_timeout_s if timeout_s is None else timeout_s
        try:
            return future.value(int(timeout * 1000))
        except RuntimeError as exc:
            self._raise_if_lost(what)
            if "timeout" in str(exc).lower():
                self.unresponsive = True
                raise RobotNotResponding(f"{what} did not answer within {timeout * 1000:.0f} ms (robot process "
                                         f"frozen or network stalled)") from None
            raise

    def _raise_if_lost(self, what: str) -> None:
        if self.lost.is_set() or not self.session.isConnected():
            self.lost.set()
            raise ConnectionLost(f"connection to {self.url} lost ({what})")

    def _async(self, method: Any, *args: Any, what: str = "a call") -> Any:
        self._raise_if_lost(what)
        try:
            return method(*args, _async=True)
        except RuntimeError:
            self._raise_if_lost(what)
            raise

    # -- Robot interface -------------------------------------------------------------------------------------
    def frame(self) -> Frame | None:
        what = "ALVideoDevice.getImageRemote"
        img = self._call(self._async(self.video.getImageRemote, self.handle, what=what), what, self.p.frame_timeout_s)
        if not img:
            return None
        w, h, layers, space = (int(v) for v in img[:4])
        data = np.frombuffer(bytes(img[6]), dtype=np.uint8)
        if data.size != w * h * layers or layers != 3:
            raise RuntimeError(f"ALVideoDevice.getImageRemote: {data.size} bytes for {w}x{h}x{layers}")
        rgb = data.reshape(h, w, 3)
        return Frame(rgb[..., ::-1].copy() if space == BGR else rgb, float(img[4]) + 1e-6 * float(img[5]))

    def odometry(self) -> Odometry:
        pos = self._async(self.motion.getRobotPosition, True, what="ALMotion.getRobotPosition")
        vel = self._async(self.motion.getRobotVelocity, what="ALMotion.getRobotVelocity")
        pose = self._call(pos, "ALMotion.getRobotPosition")
        velocity = self._call(vel, "ALMotion.getRobotVelocity")
        return Odometry(np.asarray(pose, dtype=float)[:3], np.asarray(velocity, dtype=float)[:3], time.monotonic())

    def ranges(self) -> RangeScan | None:
        """The base's range returns (``ranges.scan_points``); None without the keys. ALMemory holds each laser's last
        frame (6.66 a second) without its time: stamped half a frame before receipt, its mean age."""
        if self.memory is None:
            return None
        what = "ALMemory.getListData"
        values = self._call(self._async(self.memory.getListData, list(KEYS), what=what), what)
        points, sonars = scan_points(values)
        return RangeScan(points, time.monotonic() - 0.5 / RANGES.laser_hz, sonars)  # at a frame's mean age

    def send(self, cmd: np.ndarray) -> np.ndarray:
        c = clamp_command(cmd, self.limits)
        self.stopped = False
        move = self._async(self.motion.move, float(c[0]), float(c[1]), float(c[2]), what="ALMotion.move")
        beat = self._async(self.watchdog.heartbeat, what="SSBLWatchdog.heartbeat") if self.watchdog else None
        self._call(move, "ALMotion.move")
        if beat is not None:
            self._call(beat, "SSBLWatchdog.heartbeat")
        return c

    def stop(self) -> None:
        """``stopMove``, tried again until one is answered or ``stop_retry_s`` has passed (each try bounded by
        ``call_timeout_s``); raises the last try's fault, at once on a lost connection. An answered stop shows
        the robot responsive again (``unresponsive`` cleared), so ``close`` still releases it."""
        end = time.monotonic() + self.p.stop_retry_s
        while True:
            left = end - time.monotonic()
            try:
                self._call(self._async(self.motion.stopMove, what="ALMotion.stopMove"), "ALMotion.stopMove",
                           min(self.p.call_timeout_s, max(left, 0.05)))
            except ConnectionLost:
                raise
            except (RobotNotResponding, RuntimeError):
                if time.monotonic() >= end:
                    raise
                time.sleep(0.02)  # an error may answer at once: no spinning
                continue
            self.stopped, self.unresponsive = True, False
            return

    def events(self) -> list[dict[str, Any]]:
        """ALMotion/MoveFailed events since the last call (collision protection refusing or stopping a move)."""
        out, self.move_failed = self.move_failed, []
        return out

    def close(self) -> None:
        """Stop (unless a stop was answered since the last move), disarm the watchdog, release the camera and
        disconnect; never raises, and runs once. Best effort: after a lost connection, or a call that timed out
        with no stop answered since, nothing more is tried, so a frozen robot costs no further timeout. The
        watchdog is disarmed only once a stop was answered: otherwise it stays armed and stops the base itself
        when the heartbeats stay away."""
        if self.closed:
            return
        self.closed = True
        if not self.stopped:
            self._attempt(self.stop)
        if self.watchdog is not None and self.stopped:
            self._attempt(lambda: self._call(self._async(self.watchdog.disarm, what="disarm"), "SSBLWatchdog.disarm"))
        if self.handle is not None:
            handle, self.handle = self.handle, None
            self._attempt(lambda: self._call(self._async(self.video.unsubscribe, handle, what="unsubscribe"),
                                             "ALVideoDevice.unsubscribe"))
        if self.sonar is not None:  # the sonars stop emitting once nobody subscribes
            sonar, self.sonar = self.sonar, None
            self._attempt(lambda: self._call(self._async(sonar.unsubscribe, SONAR_SUBSCRIBER, what="unsubscribe"),
                                             "ALSonar.unsubscribe"))
        self._subscribers.clear()
        try:
            self.session.close()
        except RuntimeError:
            pass

    def _attempt(self, step: Any) -> bool:
        """Run one closing step unless the robot is gone or frozen; whether it returned."""
        if self.lost.is_set() or self.unresponsive:
            return False
        try:
            step()
            return True
        except RobotNotResponding:
            self.unresponsive = True
        except (RuntimeError, ConnectionLost, AttributeError):
            pass
        return False


def check_watchdog(robot: NaoqiRobot, url: str, no_watchdog: bool) -> str | None:
    """Refuse a run whose base nothing would stop if deploy died: a robot without the ``SSBLWatchdog`` service,
    unless ``--no-watchdog`` and the robot is the virtual Pepper (its ``SSBLVirtualPepper`` identity); the flag
    is refused for any other robot. Returns the warning to print when running without a watchdog."""
    virtual = robot.identity is not None
    start = f"start python -m ssbl_pb.deploy.watchdog --robot {url} beside it (docs/deploy.md)"
    if no_watchdog and not virtual:
        raise UserError(f"--no-watchdog: {url} is not the virtual Pepper, and if deploy died a real base would keep "
                        f"its last command: {start} and drop --no-watchdog")
    if robot.watchdog is None and not no_watchdog:
        raise UserError(f"{url}: no SSBLWatchdog service: if this process died the base would keep its last command; "
                        + (f"{start}, or (a virtual Pepper) pass --no-watchdog" if virtual else start))
    if robot.watchdog is None:
        return "warning: --no-watchdog: if this process dies the virtual base keeps its last command"
    return None
