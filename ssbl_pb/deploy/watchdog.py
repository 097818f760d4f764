"""A watchdog beside ALMotion: stops the base when the deploy process stops sending heartbeats.

    python -m ssbl_pb.deploy.watchdog --robot tcp://192.168.1.20:9559          # on a machine next to the robot
    python3 watchdog.py --robot tcp://127.0.0.1:9559                          # this file alone, on the robot

NAOqi has no command watchdog: if the deploy process dies (kill -9, a laptop losing power or Wi-Fi) the base
keeps its last ``move``. This registers a ``SSBLWatchdog`` service on the robot; the deploy loop calls its
``heartbeat()`` with every command (10 Hz) and ``disarm()`` when it ends normally. When heartbeats stop for
longer than ``--limit`` (default 0.5 s, as ROS ``cmd_vel`` multiplexers and lerobot's base watchdog) while
armed, it calls ``ALMotion.stopMove()`` and sends it again every 0.1 s until the robot's own velocity
(``ALMotion.getRobotVelocity()``) reads zero: a stop answered late, or answered without effect, does not count.
Nothing waits on the robot (every call is asynchronous), and a heartbeat arriving meanwhile (deploy resuming
after a stall) cancels the stop in progress instead of being disarmed by it. It needs only Python 3 and ``qi``
(no numpy, no ssbl_pb), so the file can be copied onto the robot; docs/deploy.md says how. Exit: 130 on Ctrl-C,
143 on SIGTERM (and SIGHUP, unless started under nohup), 2 on bad flags or if the robot cannot be reached, 7
when the connection to the robot is lost (the base can no longer be stopped from here).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

try:  # inside the package: its error type and command-line contract
    from ssbl_pb.cli import ArgumentParser, run_without_teardown
    from ssbl_pb.errors import UserError
except ImportError:  # copied alone onto the robot: plain qi, the same contract in brief
    UserError = ValueError  # type: ignore[misc, assignment]

    class ArgumentParser(argparse.ArgumentParser):  # type: ignore[no-redef]
        """One ``error:`` line for a bad flag instead of argparse's usage block."""

        def error(self, message: str) -> None:  # type: ignore[override]
            raise ValueError(f"{message} (see --help)")

    def _interrupt(signum, frame):  # type: ignore[no-untyped-def]
        raise KeyboardInterrupt(signum)

    def run_without_teardown(main):  # type: ignore[no-redef]
        """A ``ValueError`` is one line and exit 2; Ctrl-C exits 130, SIGTERM and SIGHUP 143 (the package's); the
        exit skips the interpreter's teardown, where libqi's finalizers may abort."""
        signal.signal(signal.SIGTERM, _interrupt)
        if signal.getsignal(signal.SIGHUP) is not signal.SIG_IGN:  # nohup: the user asked to outlive the shell
            signal.signal(signal.SIGHUP, _interrupt)
        try:
            code = main(None)
        except ValueError as exc:
            _say(f"error: {exc}", sys.stderr)
            code = 2
        except KeyboardInterrupt as exc:
            code = 143 if exc.args in ((signal.SIGTERM,), (signal.SIGHUP,)) else 130
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

SERVICE = "SSBLWatchdog"
EXIT_LOST = 7  # as deploy's connection_lost
LIMIT_S = 0.5  # s without a heartbeat before the first stopMove (ROS cmd_vel multiplexers, lerobot)
RETRY_S = 0.1  # s between stopMove sends until the base reads still: a lost or idle stop costs one period
TICK_S = 0.02  # s between checks: the stop goes out at most this late after the limit
STILL = 0.01  # m/s and rad/s: getRobotVelocity below this on every axis is a base at rest (a tenth of the
#   task's stop speed, 0.1 m/s; Pepper decelerating at 0.3 m/s^2 passes it 33 ms before standing)
KEEP = 20  # velocity readings polled at most (a robot silent for long: the oldest are let go)


def _say(line: str, stream: object = None) -> None:
    """A console line that cannot end the watchdog (a closed terminal or pipe raises on write)."""
    try:
        print(line, file=stream or sys.stdout, flush=True)
    except (OSError, ValueError):  # ValueError: the stream was closed
        pass


class Watchdog:
    """The service: ``heartbeat`` arms it, ``disarm`` ends a run cleanly; ``_expire`` (private, so qi does not
    export it) stops the base when an armed watchdog has heard nothing for ``limit_s``: ``stopMove`` every
    ``retry_s`` until a ``getRobotVelocity`` reading, asked after a stop went out, is all below ``STILL``.

    Each heartbeat or disarm starts a new generation (``gen``); a stop in progress belongs to the generation it
    began in, and every change it makes (recording a stop, disarming) is checked under the lock against the
    generation of now: a heartbeat that arrives while ``_expire`` acts leaves the run armed and the next expiry
    starts afresh. ``say``: where the console lines go (default stdout)."""

    def __init__(self, motion: object, limit_s: float = LIMIT_S, retry_s: float = RETRY_S,
                 say: object = None) -> None:
        self.motion, self.limit_s, self.retry_s = motion, limit_s, retry_s
        self._say = say or _say
        self.last = 0.0
        self.armed = False
        self.gen = 0  # heartbeats and disarms so far
        self.beats = 0
        self.stops = 0  # stops confirmed by the robot's velocity
        self.sent = 0  # stopMove calls sent, all expiries
        self._lock = threading.Lock()
        self._reset()

    def _reset(self) -> None:
        """A new expiry: no stop sent, no velocity asked (called under the lock)."""
        self._sent_here = 0
        self._sent_at = -float("inf")
        self._asked_at = -float("inf")
        self._readings: list[object] = []  # getRobotVelocity futures asked after this expiry's first stop

    def heartbeat(self) -> int:
        with self._lock:
            self.last, self.armed = time.monotonic(), True
            self.gen += 1
            self.beats += 1
            self._reset()  # deploy is alive again: it commands the base
            return self.beats

    def disarm(self) -> None:
        with self._lock:
            self.armed = False
            self.gen += 1
            self._reset()

    def _expire(self, now: float) -> str | None:
        """One tick: ``"sent"`` when heartbeats stopped and the first ``stopMove`` went out, ``"retry"`` when one
        was sent again (the base not yet read still), ``"stopped"`` when the robot's velocity read zero after a
        stop (then disarmed), None otherwise. Never raises for the robot's sake: a failed call is tried again."""
        with self._lock:
            if not (self.armed and now - self.last > self.limit_s):
                return None
            gen, readings = self.gen, list(self._readings)
            due = now - self._sent_at >= self.retry_s - 0.5 * TICK_S  # (ticks come a little late, not early)
        if any(_still(fut) for fut in readings):
            with self._lock:
                if self.gen != gen:  # a heartbeat came meanwhile: deploy drives again, the run stays armed
                    return None
                self.armed = False
                self.gen += 1
                self._reset()
                self.stops += 1
            return "stopped"
        what = None
        if due:
            try:
                self.motion.stopMove(_async=True)
                sent = True
            except Exception:  # noqa: BLE001 - qi raises RuntimeError (and more) when the call cannot go out
                sent = False
            with self._lock:
                if self.gen != gen:
                    return None
                self._sent_at = now
                if sent:
                    self.sent += 1
                    self._sent_here += 1
                    what = "sent" if self._sent_here == 1 else "retry"
                    self._asked_at = -float("inf")  # a reading after this stop
        self._ask(gen, now)
        return what

    def _ask(self, gen: int, now: float) -> None:
        """Ask the robot's velocity once a stop has gone out, a reading at a time (a new one when the last was
        answered or went a retry period without an answer)."""
        with self._lock:
            if self.gen != gen or self._sent_here == 0:
                return
            waiting = self._readings and not _answered(self._readings[-1])
            if waiting and now - self._asked_at < self.retry_s:
                return
            self._asked_at = now
        try:
            fut = self.motion.getRobotVelocity(_async=True)
        except Exception:  # noqa: BLE001 - asked again at the next tick
            return
        with self._lock:
            if self.gen == gen:
                self._readings = [f for f in self._readings if not _answered(f)][-(KEEP - 1):] + [fut]


def _answered(fut: object) -> bool:
    try:
        return bool(fut.isFinished())  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001 - a broken future will not answer
        return True


def _still(fut: object) -> bool:
    """A velocity reading that arrived, without error, with every axis below ``STILL``."""
    try:
        if not fut.isFinished() or fut.hasError():  # type: ignore[attr-defined]
            return False
        velocity = [float(v) for v in fut.value(0)]  # type: ignore[attr-defined]
    except Exception:  # noqa: BLE001 - a broken or malformed reading is not a stop
        return False
    return len(velocity) == 3 and all(abs(v) < STILL for v in velocity)


def _tick(dog: Watchdog, now: float) -> None:
    """One watchdog tick with its console line; nothing raised here may end the watchdog."""
    try:
        what = dog._expire(now)
    except Exception as exc:  # noqa: BLE001 - a bug here must not stop the watching: report, go on
        dog._say(f"watchdog tick failed ({type(exc).__name__}: {exc}); still armed")
        return
    stamp = time.strftime("%H:%M:%S")
    if what == "sent":
        dog._say(f"heartbeats stopped: stopMove sent ({stamp})")
    elif what == "retry" and dog._sent_here % 10 == 2:  # the first resend, then about once a second
        dog._say(f"base not yet still: stopMove sent again ({dog._sent_here} sent, {stamp})")
    elif what == "stopped":
        dog._say(f"base still (getRobotVelocity ~0): stop confirmed ({stamp})")


def watch(dog: Watchdog, done: threading.Event | None = None, tick_s: float = TICK_S) -> None:
    """Tick ``dog`` every ``tick_s`` until ``done`` is set."""
    done = done or threading.Event()
    while not done.is_set():
        _tick(dog, time.monotonic())
        time.sleep(tick_s)


def host(session: object, limit_s: float = LIMIT_S, say: object = None) -> tuple[Watchdog, threading.Event]:
    """Register a watchdog on ``session`` (its ``ALMotion`` asked from the same session) and tick it in a daemon
    thread until the returned event is set: a robot that serves the watchdog itself (the virtual Pepper)."""
    motion = session.service("ALMotion", _async=True).value(3000)  # type: ignore[attr-defined]
    dog = Watchdog(motion, limit_s, say=say)
    session.registerService(SERVICE, dog)  # type: ignore[attr-defined]
    done = threading.Event()
    threading.Thread(target=watch, args=(dog, done), name="watchdog", daemon=True).start()
    return dog, done


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", default="tcp://127.0.0.1:9559", help="qi URL of the robot (default %(default)s)")
    ap.add_argument("--limit", type=float, default=LIMIT_S, help="seconds without a heartbeat before stopMove")
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
        # lazy: optional, this file also runs alone on the robot without the package (2.9 logins need it)
        from ssbl_pb.deploy.naoqi import _Authenticator

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
    _say(f"watchdog on {args.robot}: stopMove after {args.limit:g} s without a heartbeat")
    try:
        watch(dog, lost)
    finally:
        session.close()
    _say(f"error: connection to {args.robot} lost; the watchdog can no longer stop the base", sys.stderr)
    return EXIT_LOST


if __name__ == "__main__":
    run_without_teardown(main)
