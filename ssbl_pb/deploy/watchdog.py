"""A watchdog beside ALMotion: stops the base when the deploy process stops sending heartbeats.

    python -m ssbl_pb.deploy.watchdog --robot tcp://192.168.1.20:9559          # on a machine next to the robot
    python3 watchdog.py --robot tcp://127.0.0.1:9559                          # this file alone, on the robot

NAOqi has no command watchdog: if the deploy process dies (kill -9, a laptop losing power or Wi-Fi) the base
keeps its last ``move``. This registers a ``SSBLWatchdog`` service on the robot; the deploy loop calls its
``heartbeat()`` with every command (10 Hz) and ``disarm()`` when it ends normally. When heartbeats stop for
longer than ``--limit`` (default 0.5 s, as ROS ``cmd_vel`` multiplexers and lerobot's base watchdog) while
armed, it calls ``ALMotion.stopMove()``, and it stays armed, sending it again every ``--retry`` seconds, until
ALMotion confirms one (a slow or lost answer must not end the one process whose job is to stop the base).
It needs only Python 3 and ``qi`` (no numpy, no ssbl_pb), so the file can be copied onto the robot;
docs/deploy.md says how. Exit: 130 on Ctrl-C, 143 on SIGTERM, 2 on bad flags or if the robot cannot be reached,
7 when the connection to the robot is lost (the base can no longer be stopped from here).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

try:  # inside the package: its error type and command-line contract
    from ssbl_pb.cli import ArgumentParser, run
    from ssbl_pb.errors import UserError
except ImportError:  # copied alone onto the robot: plain qi, the same contract in brief
    UserError = ValueError  # type: ignore[misc, assignment]

    class ArgumentParser(argparse.ArgumentParser):  # type: ignore[no-redef]
        """One ``error:`` line for a bad flag instead of argparse's usage block."""

        def error(self, message: str) -> None:  # type: ignore[override]
            raise ValueError(f"{message} (see --help)")

    def _interrupt(signum, frame):  # type: ignore[no-untyped-def]
        raise KeyboardInterrupt(signum)

    def run(main):  # type: ignore[no-redef]
        """A ``ValueError`` is one line and exit 2; Ctrl-C exits 130, SIGTERM 143 (the package's codes)."""
        signal.signal(signal.SIGTERM, _interrupt)
        try:
            code = main(None)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            code = 2
        except KeyboardInterrupt as exc:
            code = 143 if exc.args == (signal.SIGTERM,) else 130
        sys.exit(code)

SERVICE = "SSBLWatchdog"
EXIT_LOST = 7  # as deploy's connection_lost
RETRY_S = 0.1  # s an unanswered stopMove waits before the next one: a stop within 2 ticks of a lost answer
KEEP = 20  # unanswered stopMove futures polled at most (a robot silent for long: the oldest are let go)


class Watchdog:
    """The service: ``heartbeat`` arms it, ``disarm`` ends a run cleanly; ``_expire`` (private, so qi does not
    export it) stops the base when an armed watchdog has heard nothing for ``limit_s``, and keeps sending
    ``stopMove`` every ``retry_s`` until one is confirmed (its future done without error). Nothing here waits
    on the robot: a call that hangs costs one retry period, not the watchdog."""

    def __init__(self, motion: object, limit_s: float, retry_s: float = RETRY_S) -> None:
        self.motion, self.limit_s, self.retry_s = motion, limit_s, retry_s
        self.last = 0.0
        self.armed = False
        self.beats = 0
        self.stops = 0  # stops confirmed
        self.sent = 0  # stopMove calls sent
        self._pending: list[object] = []  # stopMove futures not yet answered
        self._sent_at = -float("inf")
        self._lock = threading.Lock()

    def heartbeat(self) -> int:
        with self._lock:
            self.last, self.armed = time.monotonic(), True
            self._pending = []  # deploy is alive again: it commands the base
            self.beats += 1
            return self.beats

    def disarm(self) -> None:
        with self._lock:
            self.armed = False
            self._pending = []

    def _expire(self, now: float) -> str | None:
        """One tick: ``"sent"`` when heartbeats stopped and the first ``stopMove`` went out, ``"retry"`` when an
        unanswered or failed one was sent again, ``"stopped"`` when ALMotion confirmed a stop (then disarmed),
        None otherwise. Never raises for the robot's sake: a failed call is retried at the next period."""
        with self._lock:
            if not (self.armed and now - self.last > self.limit_s):
                return None
            pending = list(self._pending)
        for fut in pending:
            try:
                done = fut.isFinished() and not fut.hasError()
            except Exception:  # noqa: BLE001 - a broken future is an unanswered stop
                done = False
            if done:
                with self._lock:
                    self.armed, self._pending = False, []
                self.stops += 1
                return "stopped"
        if pending and not _failed(pending[-1]) and now - self._sent_at < self.retry_s:  # the newest may answer
            return None
        self._sent_at = now
        try:
            fut = self.motion.stopMove(_async=True)
        except Exception:  # noqa: BLE001 - qi raises RuntimeError (and more) when the call cannot go out
            return "retry"
        self.sent += 1
        with self._lock:
            if self.armed:
                self._pending = (self._pending + [fut])[-KEEP:]
        return "sent" if not pending else "retry"


def _failed(fut: object) -> bool:
    try:
        return bool(fut.isFinished() and fut.hasError())  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001
        return True


def _tick(dog: Watchdog, now: float) -> None:
    """One watchdog tick with its console line; nothing raised here may end the watchdog."""
    try:
        what = dog._expire(now)
    except Exception as exc:  # noqa: BLE001 - a bug here must not stop the watching: report, go on
        print(f"watchdog tick failed ({type(exc).__name__}: {exc}); still armed", file=sys.stderr, flush=True)
        return
    stamp = time.strftime("%H:%M:%S")
    if what == "sent":
        print(f"heartbeats stopped: stopMove sent ({stamp})", flush=True)
    elif what == "retry" and dog.sent % 10 in (1, 2):  # the first retries, then about once a second
        print(f"stopMove not confirmed: sent again ({dog.sent} sent, {stamp})", flush=True)
    elif what == "stopped":
        print(f"stopMove confirmed by ALMotion ({stamp})", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
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
            _tick(dog, time.monotonic())
            time.sleep(0.02)
    finally:
        session.close()
    print(f"error: connection to {args.robot} lost; the watchdog can no longer stop the base", file=sys.stderr)
    return EXIT_LOST


if __name__ == "__main__":
    run(main)
