"""Run a list of trials, each into its own folder, on a local process pool or a Ray cluster; resumable.

A trial is any picklable object with a ``name`` (its folder: ``ROOT/trials/NAME/``), a ``definition()`` (a
JSON-able dict of what its result depends on) and ``__call__(trial_dir) -> dict`` (does the work, returns a
JSON-able dict of numbers). A trial is finished when ``ROOT/trials/NAME/result.json`` exists: running the same
list again runs only the others, and an unfinished trial starts again from scratch, so a result never depends on
when a run was interrupted. Each attempt's output goes to ``ROOT/logs/NAME.log``. A trial whose definition gained
keys may have ``upgrade(stored, record, trial_dir) -> dict``: an older stored definition completed from what its
run left, so results that still hold are kept.

    from ssbl_pb.sweep import run_trials                                       # (sweep.dispatch)
    outcome = run_trials(trials, Path("results/table1"), workers=2)            # local pool
    outcome = run_trials(trials, Path("/shared/table1"), address="head:6379")  # Ray Tune trials on a cluster
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import socket
import time
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

from ..errors import Terminated, UserError
from ..files import write_json

RESULT = "result.json"
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._=,+-]*$")


class Trial(Protocol):
    name: str

    def definition(self) -> dict[str, Any]: ...

    def __call__(self, trial_dir: Path) -> dict[str, Any]: ...


class TrialsFailed(RuntimeError):
    """Some trials raised (a bug, or a machine problem): their tracebacks are in their logs."""


@dataclasses.dataclass
class Outcome:
    """``records``: name -> the stored result record of every finished trial; ``failed``: name -> error text."""

    records: dict[str, dict[str, Any]]
    failed: dict[str, str]

    def raise_failures(self, root: Path) -> None:
        if self.failed:
            lines = [f"{name}: {text.strip().splitlines()[-1] if text.strip() else 'failed'}"
                     for name, text in self.failed.items()]
            raise TrialsFailed(f"{len(self.failed)} trial(s) failed (logs in {root / 'logs'}):\n" + "\n".join(lines))


def trial_dir(root: Path, name: str) -> Path:
    return root / "trials" / name


def check_trials(trials: Sequence[Trial]) -> None:
    """Names are unique and safe as folder names."""
    seen: set[str] = set()
    for t in trials:
        if not isinstance(t.name, str) or not NAME_RE.match(t.name) or len(t.name) > 200:
            raise UserError(f"trial name {t.name!r}: expected letters, digits and . _ = , + - (at most 200)")
        if t.name in seen:
            raise UserError(f"trial name {t.name!r}: used twice")
        seen.add(t.name)


def _normal(data: Any) -> Any:
    return json.loads(json.dumps(data, sort_keys=True, default=str))


def finished(root: Path, trials: Sequence[Trial]) -> dict[str, dict[str, Any]]:
    """The stored records of the finished trials; a record of another definition (the spec or its base config
    changed since) is refused, naming the trial, rather than mixed into a summary."""
    out: dict[str, dict[str, Any]] = {}
    for t in trials:
        path = trial_dir(root, t.name) / RESULT
        if not path.is_file():
            continue
        try:
            record = json.loads(path.read_text())
            stored = record["task"]
        except (ValueError, KeyError, TypeError):
            continue  # unreadable: run the trial again
        current = _normal(t.definition())
        if stored != current and hasattr(t, "upgrade"):
            stored = _normal(t.upgrade(stored, record, trial_dir(root, t.name)))
        if stored != current:
            keys = set(stored) | set(current) if isinstance(stored, dict) else set(current)
            changed = sorted(k for k in keys if not isinstance(stored, dict) or stored.get(k) != current.get(k))
            raise UserError(f"{path}: trial {t.name} was run with another definition ({', '.join(changed)} changed "
                            f"since: the spec, its base config, the evaluation, the reward or an encoder file); use "
                            f"another --out, or remove {path.parent}")
        out[t.name] = record
    return out


def run_task(task: Trial, root: Path, node_id: str | None = None) -> dict[str, Any]:
    """Run one trial in this process (its output appended to its log) and store its result record."""
    folder = trial_dir(root, task.name)
    log = root / "logs" / f"{task.name}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    with open(log, "a") as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
        print(f"== {time.strftime('%Y-%m-%d %H:%M:%S')} on {socket.gethostname()} (pid {os.getpid()})", flush=True)
        try:
            result = task(folder)
        except KeyboardInterrupt as exc:  # stopped (Ctrl-C, SIGTERM): no traceback, the trial runs again next time
            print(f"== stopped by {'SIGTERM' if isinstance(exc, Terminated) else 'Ctrl-C'}; unfinished", flush=True)
            raise
        except BaseException:
            traceback.print_exc()
            raise
    record = {"name": task.name, "task": _normal(task.definition()), "result": _normal(result),
              "node": socket.gethostname(), "node_id": node_id, "pid": os.getpid(),
              "wall_s": round(time.time() - t0, 2), "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}
    write_json(folder / RESULT, record)
    return record


__all__ = ["RESULT", "Outcome", "Trial", "TrialsFailed", "check_trials", "finished", "run_task", "trial_dir"]
