"""A watchdog beside ALMotion: stops the base when the deploy process stops sending heartbeats.

    python -m ssbl_pb.deploy.watchdog --robot tcp://192.168.1.20:9559          # on a machine next to the robot
    python3 watchdog.py --robot tcp://127.0.0.1:9559                          # this file alone, on the robot

NAOqi has no command watchdog: if the deploy process dies (kill -9, a laptop losing power or Wi-Fi) the base
keeps its last ``move``. This registers a ``SSBLWatchdog`` service on the robot; the deploy loop calls its
``heartbeat()`` with every command (10 Hz) and ``disarm()`` when it ends normally. When heartbeats stop for
longer than ``--limit`` (default 0.5 s, as ROS ``cmd_vel`` multiplexers and lerobot's base watchdog) while
armed, it calls ``ALMotion.stopMove()``. It needs only Python 3 and ``qi`` (no numpy, no ssbl_pb), so the file
can be copied onto the robot; docs/deploy.md says how. Exit: 0 on Ctrl-C/SIGTERM, 2 if the robot cannot be
reached, 7 when the connection to the robot is lost (the base can no longer be stopped from here).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

try:  # inside the package: its error type and command-line contract
    from ssbl_pb.cli import run
    from ssbl_pb.errors import UserError
except ImportError:  # copied alone onto the robot: plain qi
    UserError = ValueError  # type: ignore[misc, assignment]

    def _interrupt(signum, frame):  # type: ignore[no-untyped-def]
        raise KeyboardInterrupt

    def run(main):  # type: ignore[no-redef]
        """The package's contract in brief: a ``ValueError`` is one line and exit 2; Ctrl-C/SIGTERM exit."""
        signal.signal(signal.SIGTERM, _interrupt)
        try:
            code = main(None)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            code = 2
        except KeyboardInterrupt:
            code = 0
        sys.exit(code)

SERVICE = "SSBLWatchdog"
EXIT_LOST = 7  # as deploy's connection_lost


class Watchdog:
    """The service: ``heartbeat`` arms it, ``disarm`` ends a run cleanly; ``_expire`` (private, so qi does not
    export it) stops the base when an armed watchdog has heard nothing for ``limit_s``."""

    def __init__(self, motion: object, limit_s: float, timeout_ms: int = 300) -> None:
        self.motion, self.limit_s, self.timeout_ms = motion, limit_s, timeout_ms
        self.last = 0.0
        self.armed = False
        self.beats = 0
        self.stops = 0
        self._lock = threading.Lock()

    def heartbeat(self) -> int:
        with self._lock:
            self.last, self.armed = time.monotonic(), True
            self.beats += 1
            return self.beats

    def disarm(self) -> None:
        with self._lock:
            self.armed = False

    def _expire(self, now: float) -> bool:
        """Stop the base if armed and silent for ``limit_s``; True when it did."""
        with self._lock:
            if not (self.armed and now - self.last > self.limit_s):
                return False
            self.armed = False
        self.motion.stopMove(_async=True).value(self.timeout_ms)
        self.stops += 1
        return True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", default="tcp://127.0.0.1:9559", help="qi URL of the robot (default %(default)s)")
    ap.add_argument("--limit", type=float, default=0.5, help="seconds without a heartbeat before stopMove")
    ap.add_argument("--user", help="NAOqi 2.9 login user")
    ap.add_argument("--token", help="NAOqi 2.9 login token")
    args = ap.parse_args(argv)
    if not 0.05 <= args.limit <= 10:
        raise UserError(f"--limit {args.limit}: expected seconds in [0.05, 10]")
    try:
        import qi
    except ImportError:
        raise UserError("the watchdog needs NAOqi's 'qi' package (pip install qi)") from None
    qi.logging.setLevel(qi.logging.ERROR)
    session = qi.Session()
    if args.user is not None or args.token is not None:
        from ssbl_pb.deploy.naoqi import _Authenticator  # 2.9 logins: only with the package

        session.setClientAuthenticatorFactory(_Authenticator(args.user or "nao", args.token or ""))
    try:
        session.connect(args.robot, _async=True).value(3000)
        motion = session.service("ALMotion", _async=True).value(3000)
    except RuntimeError as exc:
        raise UserError(f"--robot {args.robot}: cannot reach ALMotion within 3 s ({exc})") from None
    lost = threading.Event()
    session.disconnected.connect(lambda *_: lost.set())
    dog = Watchdog(motion, args.limit)
    session.registerService(SERVICE, dog)
    print(f"watchdog on {args.robot}: stopMove after {args.limit:g} s without a heartbeat", flush=True)
    try:
        while not lost.is_set():
            if dog._expire(time.monotonic()):
                print(f"heartbeats stopped: stopMove sent ({time.strftime('%H:%M:%S')})", flush=True)
            time.sleep(0.02)
    finally:
        session.close()
    print(f"error: connection to {args.robot} lost; the watchdog can no longer stop the base", file=sys.stderr)
    return EXIT_LOST


if __name__ == "__main__":
    run(main)
