"""What every command-line tool shares: the error exit, signals, progress bars.

A tool's ``if __name__ == "__main__": run(main)`` gives it the contract the README promises: a ``UserError`` is
one line on stderr and exit 2; Ctrl-C exits 130 and SIGTERM 143 with one line (code that must save or stop
first catches ``KeyboardInterrupt``, which SIGTERM raises too, as ``Terminated``), also when a shell started the
tool in the background (with SIGINT ignored); SIGHUP (the terminal or the ssh connection closed) is SIGTERM's
twin, unless the tool was started under ``nohup``; any other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, NoReturn, TypeVar

from .errors import EXIT_SIGINT, EXIT_SIGTERM, EXIT_USAGE, Terminated, UserError

T = TypeVar("T")

__all__ = ["EXIT_USAGE", "ArgumentParser", "UserError", "fail", "run", "progress", "progress_bar", "make_bar",
           "int_at_least", "int_in", "float_in", "command_line"]


def fail(exc: BaseException | str) -> int:
    """Print a one-line error to stderr; returns the usage exit code (2)."""
    text = " ".join(str(exc).split()) if not isinstance(exc, str) else exc
    print(f"error: {text}", file=sys.stderr)
    return EXIT_USAGE


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose errors are the tools' one line (``error: argument --x: ...``, exit 2) instead of the usage
    block; ``--help`` is unchanged. Raw-description help by default, so docstring examples keep their layout."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise UserError(f"{message} (see --help)")

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        if kwargs.get("type") is Path:  # an empty path would be the current folder: refused
            kwargs["type"] = _path
        return super().add_argument(*args, **kwargs)


def _path(text: str) -> Path:
    """An argparse type: a path, not an empty string (``Path("")`` is ``.``, the folder the tool runs in)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected a path (an empty one would be the current folder)")
    return Path(text)


def int_at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``."""
    return int_in(low, None)


def int_in(low: int, high: int | None) -> Callable[[str], int]:
    """An argparse type: an integer in [low, high] (no upper bound when ``high`` is None)."""
    want = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {want}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"{value}: expected {want}")
        return value

    parse.__name__ = want  # argparse names the type in some messages
    return parse


def float_in(low: float, high: float, low_open: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number in [low, high] (``(low, high]`` when ``low_open``); NaN and inf are
    refused, as are numbers that argparse's ``float`` alone would let through."""
    want = f"a number in {'(' if low_open else '['}{low:g}, {high:g}]"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {want}") from None
        if not (math.isfinite(value) and (value > low if low_open else value >= low) and value <= high):
            raise argparse.ArgumentTypeError(f"{text}: expected {want}")
        return value

    parse.__name__ = want
    return parse


def command_line(tool: str, argv: list[str] | None = None) -> str:
    """``python TOOL ARGS`` as typed (``argv``, else this process's arguments), for reports that say how they
    were made."""
    import shlex

    return " ".join(["python", tool, *(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))])


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated(signal.Signals(signum).name)


def run(main: Callable[..., int], argv: list[str] | None = None) -> NoReturn:
    """Run a tool's ``main(argv) -> exit code`` under the contract above and exit with its code."""
    with contextlib.suppress(ValueError):  # not the main thread (tests calling run): leave the handlers alone
        signal.signal(signal.SIGTERM, _raise_terminated)
        if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) is not signal.SIG_IGN:  # not under nohup
            signal.signal(signal.SIGHUP, _raise_terminated)
        # a shell starts background jobs with SIGINT ignored, and Python then installs no handler of its own
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        code = main(argv)
    except UserError as exc:
        code = fail(exc)
    except Terminated as sig:
        _tell(f"terminated ({sig.args[0] if sig.args else 'SIGTERM'})")
        code = EXIT_SIGTERM
    except KeyboardInterrupt:
        _tell("interrupted (Ctrl-C)")
        code = EXIT_SIGINT
    sys.exit(code)


def run_without_teardown(main: Callable[..., int]) -> NoReturn:
    """``run(main)``, then exit without the interpreter's teardown: once the tool's work is done (files written, the
    base stopped), native finalizers (libqi's threads and others) take ~0.5 s, and libqi's may abort the process
    (SIGABRT instead of the exit code: 1 in 4 SIGTERMed watchdogs on a loaded machine)."""
    try:
        run(main)
    except SystemExit as done:
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(done.code if isinstance(done.code, int) else 1)


def _tell(line: str) -> None:
    """The exit line on stderr; a terminal gone with the SIGHUP that ended the tool must not change its code."""
    with contextlib.suppress(OSError, ValueError):
        print(line, file=sys.stderr)


def die_with_parent(parent: int) -> None:
    """In a worker process: be killed when the process ``parent`` (its parent's pid) ends, even by SIGKILL
    (Linux: ``PR_SET_PDEATHSIG``; elsewhere a daemon thread polls the parent pid each second)."""
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
            if os.getppid() != parent:  # the parent died before the call
                os._exit(1)
            return

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="die-with-parent").start()


@contextlib.contextmanager
def children_ignore_sigint() -> Iterator[None]:
    """Processes started inside ignore SIGINT from their first instruction (SIG_IGN survives exec), so a Ctrl-C
    while a worker still imports prints no traceback there; only the parent reports it. A Ctrl-C meanwhile is
    held (blocked, not lost) and reaches the parent as the block ends."""
    if threading.current_thread() is not threading.main_thread():  # signals reach the main thread only
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})  # blocked first: a SIGINT now stays pending
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL if old is None else old)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


class DeferredSignals:
    """Within ``with``: SIGINT/SIGTERM only set ``signum`` (code polls it and stops at a safe point); a second
    signal raises at once. On exit the previous handlers return. Outside the main thread (a Ray Tune trial runs
    in one) it does nothing: signals reach only the main thread."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self._saved: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        if self.signum is not None:  # asked twice: stop now
            raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()
        self.signum = signum
        print("\nstopping at the next safe point (signal again to stop at once)", file=sys.stderr, flush=True)

    def __enter__(self) -> DeferredSignals:
        if threading.current_thread() is not threading.main_thread():
            return self
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._saved[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc: Any) -> None:
        for sig, old in self._saved.items():
            signal.signal(sig, old)

    def raise_if_signalled(self) -> None:
        """Re-raise the deferred signal as the exception ``run`` maps to its exit code."""
        if self.signum == signal.SIGTERM:
            raise Terminated()
        if self.signum is not None:
            raise KeyboardInterrupt()


def stderr_is_tty() -> bool:
    return hasattr(sys.stderr, "isatty") and sys.stderr.isatty()


class PlainBar:
    """A progress bar for logs: one plain line at every 10 % (and at most every 30 s otherwise), no ``\\r``."""

    def __init__(self, total: int, desc: str, unit: str, initial: int = 0) -> None:
        self.total, self.desc, self.unit, self.n = max(int(total), 0), desc, unit, int(initial)
        self.postfix, self._t0 = "", time.monotonic()
        self._last_t, self._last_decile = self._t0, self._decile()

    def _decile(self) -> int:
        return 10 * self.n // self.total if self.total else 0

    def update(self, k: int = 1) -> None:
        self.n += int(k)
        now = time.monotonic()
        if self._decile() > self._last_decile or now - self._last_t >= 30.0:
            self._last_decile, self._last_t = self._decile(), now
            self._emit()

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def _emit(self) -> None:
        pct = f"{100 * self.n / self.total:3.0f} %" if self.total else ""
        extra = f", {self.postfix}" if self.postfix else ""
        print(f"{self.desc}: {pct} ({self.n}/{self.total} {self.unit}, {time.monotonic() - self._t0:.0f} s{extra})",
              file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.n and self._last_decile < 10:
            self._emit()


def make_bar(total: int, desc: str, unit: str = "it", initial: int = 0) -> Any:
    """A tqdm bar on a terminal, a ``PlainBar`` otherwise (``update``, ``set_postfix_str``, ``close``)."""
    if not stderr_is_tty() or os.environ.get("SSBL_PLAIN_PROGRESS"):
        return PlainBar(total, desc, unit, initial)
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit=unit, dynamic_ncols=True, mininterval=0.5)


def progress(items: Iterable[T], desc: str, unit: str = "it", total: int | None = None) -> Iterator[T]:
    """``items`` with a ``make_bar`` progress bar (``total`` defaults to ``len(items)``)."""
    bar = make_bar(len(items) if total is None else total, desc, unit)  # type: ignore[arg-type]
    try:
        for item in items:
            yield item
            bar.update(1)
    finally:
        bar.close()


@contextlib.contextmanager
def progress_bar(total: int, desc: str, unit: str = "ep") -> Iterator[Callable[[int], None]]:
    """``make_bar`` as a callable ``advance(n)``, closed on exit."""
    bar = make_bar(total, desc, unit)
    try:
        yield bar.update
    finally:
        bar.close()
