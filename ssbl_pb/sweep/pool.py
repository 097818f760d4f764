"""The local process pool (no Ray): ``workers`` spawned processes, each running one trial at a time and kept for
the next one (the imports of torch and SB3 cost seconds, paid once per worker), each in a session of its own.

The pool, not ``concurrent.futures``, so that an interrupted sweep stops its trials at once: on Ctrl-C, SIGTERM
or an error the parent terminates every worker, and a worker whose parent dies (``kill -9``) is killed by the
kernel (Linux; elsewhere it exits within a second by itself), so no orphan keeps writing into a trial folder that
the next run starts again.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from ..cli import children_ignore_sigint
from ..errors import EXIT_SIGINT, EXIT_SIGTERM, Terminated
from .runner import Trial, run_task


class _Worker:
    def __init__(self, ctx: Any) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, os.getpid()), daemon=True)
        try:
            with children_ignore_sigint():
                self.proc.start()
        except BaseException:  # a Ctrl-C held back during the start: this worker goes with the others
            if self.proc.pid is not None:
                self.proc.kill()
                self.proc.join()
            raise
        child.close()
        self.task: Trial | None = None

    def give(self, task: Trial, root: Path) -> None:
        self.task = task
        self.conn.send((task, str(root)))

    def close(self, wait_s: float) -> None:
        """Ask the worker to exit (terminate it after ``wait_s``, kill it if that does not end it)."""
        if self.proc.is_alive() and self.task is None:
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.proc.join(wait_s)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(5.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


def run_local(trials: Sequence[Trial], root: Path, workers: int,
              done: Callable[[str, dict[str, Any] | None], None]) -> dict[str, str]:
    """Run ``trials`` on ``workers`` processes; returns name -> error text of the trials that failed."""
    ctx = mp.get_context("spawn")  # no fork: torch and numba state must not be copied into trials
    queue, pool, failed = list(trials), [], {}
    clean = False
    try:
        while queue or any(w.task for w in pool):
            for w in [w for w in pool if w.task is None]:
                if not w.proc.is_alive():  # an idle worker killed from outside
                    w.close(0.0)
                    pool.remove(w)
                elif queue:
                    w.give(queue.pop(0), root)
            while queue and len(pool) < workers:
                pool.append(_Worker(ctx))
                pool[-1].give(queue.pop(0), root)
            busy = [w for w in pool if w.task is not None]
            ready = wait([w.conn for w in busy] + [w.proc.sentinel for w in busy])
            for w in busy:
                if w.conn not in ready and w.proc.sentinel not in ready:
                    continue
                name = w.task.name  # type: ignore[union-attr]
                try:
                    status, payload = w.conn.recv()
                except (EOFError, OSError):
                    w.proc.join(5.0)
                    status, payload = "error", f"worker process died (exit code {w.proc.exitcode})"
                w.task = None
                if status == "ok":
                    done(name, payload)
                    continue
                failed[name] = payload
                done(name, None)
                if not w.proc.is_alive():
                    w.close(0.0)
                    pool.remove(w)
        clean = True
    finally:
        for w in pool:
            w.close(10.0 if clean else 0.0)
    return failed


def _serve(conn: Connection, parent: int) -> None:
    """A worker: run the trials the parent sends until it sends None (or goes away)."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # one CPU per trial (torch reads these on import)
        os.environ[var] = "1"
    # the parent handles Ctrl-C and stops its workers (ignored since the start, see cli.children_ignore_sigint,
    # whose block this process need not keep)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    # a session of its own: where the kernel groups CPU time by session (autogroup, on by default in many
    # distributions), N workers then get the share of N separate runs on a busy machine, not that of one
    os.setsid()
    _die_with_parent()
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    try:
        _serve_trials(conn)
    except KeyboardInterrupt as exc:  # the parent stops its workers (a trial may re-raise the signal, as training
        # does after its safe point): leave quietly, the parent reports the interruption in one line
        raise SystemExit(EXIT_SIGTERM if isinstance(exc, Terminated) else EXIT_SIGINT) from None


def _serve_trials(conn: Connection) -> None:
    """Run each trial received on ``conn`` and send back its record or its error text, until None or EOF."""
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        task, root = job
        try:
            conn.send(("ok", run_task(task, Path(root))))
        except Exception:  # the trial's bug: its traceback goes to the parent and into the trial's log
            conn.send(("error", traceback.format_exc()))


def _die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent dies (prctl PR_SET_PDEATHSIG); elsewhere the polling thread."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def _exit_with_parent(parent: int) -> None:
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(3)
