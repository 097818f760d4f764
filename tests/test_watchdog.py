"""The watchdog without qi: a fake ALMotion whose stops and velocity readings answer as each test says. A stop
counts only once the robot's own velocity reads zero; a heartbeat that arrives while the watchdog acts (deploy
resuming after a stall) keeps the run armed; nothing it prints or meets can end it."""

from __future__ import annotations

import pytest

from ssbl_pb.deploy.watchdog import KEEP, RETRY_S, TICK_S, Watchdog, _tick


class Future:
    """A qi future as the watchdog polls it; ``on_check`` runs at the first ``isFinished`` (something that
    happens while the watchdog looks at the answer)."""

    def __init__(self, result=None, answered=True, error=False, on_check=None):
        self.result, self.answered, self.error, self.on_check = result, answered, error, on_check

    def isFinished(self):  # noqa: N802 - qi's names
        if self.on_check is not None:
            hook, self.on_check = self.on_check, None
            hook()
        return self.answered

    def hasError(self):  # noqa: N802
        return self.error

    def value(self, timeout_ms=None):
        if self.error or not self.answered:
            raise RuntimeError("Future timeout." if not self.answered else "ALMotion error")
        return self.result


class Motion:
    """ALMotion: ``stopMove`` answers at once (``stop_works``: it also stops the base, else it does nothing, as the
    virtual Pepper's ``--hang-stops``); ``getRobotVelocity`` answers the base's velocity of the moment it was
    asked. ``during_stop`` runs inside the next stopMove call, ``on_check`` when the watchdog first looks at any
    answer (each once)."""

    def __init__(self, velocity=(0.3, 0.0, 0.1), stop_works=True):
        self.velocity, self.stop_works = list(velocity), stop_works
        self.stops = self.asked = 0
        self.during_stop = self.on_check = None

    def _checked(self):
        hook, self.on_check = self.on_check, None
        if hook is not None:
            hook()

    def stopMove(self, _async=False):  # noqa: N802 - NAOqi's name
        self.stops += 1
        if self.during_stop is not None:
            hook, self.during_stop = self.during_stop, None
            hook()
        if self.stop_works:
            self.velocity = [0.0, 0.0, 0.0]  # (decelerating takes a while on the real base: see the first test)
        return Future(None, on_check=self._checked)

    def getRobotVelocity(self, _async=False):  # noqa: N802
        self.asked += 1
        return Future(list(self.velocity), on_check=self._checked)


def ticks(dog, start, seconds):
    """``_expire`` every ``TICK_S`` from ``start`` for ``seconds``: the non-None results with their times."""
    out = []
    for k in range(int(round(seconds / TICK_S))):
        what = dog._expire(start + k * TICK_S)
        if what is not None:
            out.append((round(k * TICK_S, 2), what))
    return out


def test_an_armed_watchdog_stops_the_base_and_confirms_by_its_velocity():
    motion = Motion(stop_works=False)  # the base decelerates: still moving at the first readings
    dog = Watchdog(motion, limit_s=0.5)
    assert dog._expire(100.0) is None and motion.stops == 0  # never armed: a base driven by others is left alone
    dog.heartbeat()
    t = dog.last
    assert dog._expire(t + 0.4) is None and motion.stops == 0
    assert dog._expire(t + 0.6) == "sent" and motion.stops == 1 and motion.asked == 1
    assert dog._expire(t + 0.6 + 0.5 * RETRY_S) is None and motion.stops == 1  # one retry period
    assert dog._expire(t + 0.6 + RETRY_S) == "retry" and motion.stops == 2  # not yet still: sent again
    motion.velocity = [0.0, 0.0, 0.004]  # below STILL on every axis: standing
    assert dog._expire(t + 0.6 + 1.1 * RETRY_S) is None  # the reading asked now answers at the next tick
    assert dog._expire(t + 0.6 + 1.2 * RETRY_S) == "stopped" and dog.stops == 1 and not dog.armed
    assert ticks(dog, t + 1.0, 2.0) == [] and motion.stops == 2  # disarmed until the next heartbeat
    dog.heartbeat()
    dog.disarm()  # a run that ended normally
    assert ticks(dog, dog.last + 0.6, 1.0) == [] and motion.stops == 2


def test_a_stop_answered_without_effect_is_no_confirmation():
    """The virtual Pepper's ``--hang-stops``: every stopMove answers (late or at once) and does nothing. The base
    keeps moving, so the watchdog keeps sending, one stop per retry period, and never says stopped."""
    motion = Motion(stop_works=False)
    dog = Watchdog(motion, limit_s=0.5)
    dog.heartbeat()
    said = ticks(dog, dog.last + 0.5 + TICK_S, 3.0)
    assert said[0] == (0.0, "sent") and {w for _, w in said[1:]} == {"retry"}
    assert dog.armed and dog.stops == 0
    assert motion.stops == pytest.approx(3.0 / RETRY_S, abs=2)
    motion.stop_works = True  # the next stop works: confirmed by the velocity that follows
    assert ticks(dog, dog.last + 4.0, 0.5)[-1][1] == "stopped" and not dog.armed


def test_a_heartbeat_while_the_watchdog_checks_a_stop_keeps_the_run_armed():
    """Deploy resumes after a stall just as the watchdog looks at an answer (a stop's or a velocity reading's):
    the live run is not disarmed, and the next expiry sends a stop of its own before it can confirm."""
    motion = Motion(velocity=(0.0, 0.0, 0.0))  # standing: any reading would confirm
    dog = Watchdog(motion, limit_s=0.5)
    dog.heartbeat()
    t = dog.last + 0.6
    motion.on_check = dog.heartbeat  # arrives while the first answer is being looked at
    assert dog._expire(t) == "sent"
    assert dog._expire(t + TICK_S) is None
    assert dog.armed and dog.stops == 0 and dog.beats == 2
    before = motion.stops
    said = ticks(dog, dog.last + 0.5 + TICK_S, 0.2)  # deploy stalls again
    assert said[0][1] == "sent" and said[-1][1] == "stopped" and motion.stops == before + 1


def test_a_heartbeat_while_a_stop_goes_out_starts_the_next_expiry_afresh():
    """The heartbeat lands between the decision to stop and the stop's record: that stop belongs to the run
    before; a later stall is stopped by a stop sent for it, not confirmed by the old one."""
    motion = Motion(velocity=(0.0, 0.0, 0.0))
    dog = Watchdog(motion, limit_s=0.5)
    dog.heartbeat()
    motion.during_stop = dog.heartbeat
    assert dog._expire(dog.last + 0.6) is None  # sent, but deploy came back meanwhile: nothing to confirm
    assert dog.armed and motion.stops == 1
    said = ticks(dog, dog.last + 0.5 + TICK_S, 0.2)
    assert [w for _, w in said] == ["sent", "stopped"] and motion.stops == 2


def test_calls_that_fail_or_never_answer_leave_it_armed_and_sending():
    class Failing(Motion):
        def stopMove(self, _async=False):  # noqa: N802
            self.stops += 1
            if self.stops % 2:
                raise RuntimeError("ALMotion: call cannot go out")
            return Future(error=True)

        def getRobotVelocity(self, _async=False):  # noqa: N802
            self.asked += 1
            return Future(answered=False)  # a robot that never answers

    motion = Failing()
    dog = Watchdog(motion, limit_s=0.5)
    dog.heartbeat()
    ticks(dog, dog.last + 0.5 + TICK_S, 10.0)
    assert dog.armed and dog.stops == 0
    assert motion.stops == pytest.approx(10.0 / RETRY_S, abs=2)  # one try per retry period, failed or not
    assert len(dog._readings) <= KEEP and motion.asked >= 10.0 / RETRY_S - 2


def test_a_console_gone_or_a_bug_in_a_tick_cannot_end_the_watchdog(monkeypatch):
    class Gone:
        def write(self, text):
            raise OSError(5, "Input/output error")  # the terminal closed (SIGHUP'd ssh session)

        def flush(self):
            raise OSError(5, "Input/output error")

    monkeypatch.setattr("sys.stdout", Gone())
    monkeypatch.setattr("sys.stderr", Gone())
    dog = Watchdog(Motion(), limit_s=0.5)
    dog.heartbeat()
    _tick(dog, dog.last + 0.6)  # "heartbeats stopped: stopMove sent" to a console that is gone
    assert dog.sent == 1

    class Broken(Watchdog):
        def _expire(self, now):
            raise ZeroDivisionError("boom")

    _tick(Broken(Motion(), 0.5), 1.0)  # reported (nowhere), and the loop goes on


def test_a_bug_in_a_tick_is_reported_and_the_watchdog_goes_on(capsys):
    class Broken(Watchdog):
        def _expire(self, now):
            raise ZeroDivisionError("boom")

    _tick(Broken(Motion(), 0.5), 1.0)
    assert "still armed" in capsys.readouterr().out
