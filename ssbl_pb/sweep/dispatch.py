"""``run_trials``: the unfinished trials of a list (``runner``) on a local process pool (``pool``) or a Ray
cluster (``ray_runner``)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .pool import run_local
from .ray_runner import run_on_ray
from .runner import Outcome, Trial, check_trials, finished


def run_trials(trials: Sequence[Trial], root: Path, workers: int | None = None, address: str | None = None,
               on_done: Callable[[str, dict[str, Any] | None], None] | None = None) -> Outcome:
    """Run the unfinished ``trials`` into ``root`` and return every finished one's record (see the module doc).

    Without ``address``, ``workers`` processes (spawned, one trial at a time each; default: one per core) run them
    here; with it (host:port or ``auto``), each trial is a Ray Tune trial of one CPU on that cluster, and ``root``
    must be a path every node sees; ``workers`` then caps the trials running at once (default: no cap).
    ``on_done(name, record or None)`` is called as each trial finishes (None: it failed). A trial that raises
    does not stop the others; see ``Outcome.failed``."""
    check_trials(trials)
    root = root.resolve()
    records = finished(root, trials)
    pending = [t for t in trials if t.name not in records]
    if not pending:
        return Outcome(records, {})

    def done(name: str, record: dict[str, Any] | None) -> None:
        if record is not None:
            records[name] = record
        if on_done is not None:
            on_done(name, record)

    if address is None:
        failed = run_local(pending, root, workers or os.cpu_count() or 1, done)
    else:
        failed = run_on_ray(pending, trials, root, address, workers, done)
    return Outcome(records, failed)
