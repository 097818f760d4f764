"""What tools that run trials share (``tools/sweep.py``, ``tools/table1.py``): the ``--workers``, ``--address`` and
``--storage`` options, where the trials go, and running them with a progress bar."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..cli import int_at_least, make_bar
from ..errors import UserError
from ..files import check_output_path
from .dispatch import run_trials
from .ray_runner import Probe, connect
from .runner import Outcome, Trial, finished


def add_run_options(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--workers", type=int_at_least(1),
                    help="trials at once: local processes (default: one per core); with --address, a cap (default "
                         "none: one trial per CPU of the cluster)")
    ap.add_argument("--address", help="run on the Ray cluster at HOST:PORT (its head) or 'auto' (the cluster this "
                                      "machine belongs to); without it, a local process pool and no Ray")
    ap.add_argument("--storage", type=Path, help="with --address: a folder every node sees; trials go to "
                                                 "STORAGE/<--out's name>/ (default: --out itself, which then must be "
                                                 "shared)")


class TrialsRoot:
    """Where the trials of a run go (``--out``, or ``--storage/<name of --out>`` on a cluster), checked before any
    work: ``start()`` right away (a child process tries the cluster while the caller checks its own inputs),
    ``connect()`` once those are checked."""

    def __init__(self, args: argparse.Namespace) -> None:
        if args.storage is not None and args.address is None:
            raise UserError(f"--storage {args.storage}: only with --address (a local run writes into --out)")
        check_output_path(args.out, "--out")
        self.address, self.workers = args.address, args.workers
        root = args.out
        self.probe: Any = None
        if args.address is not None:
            if args.storage is not None:
                check_output_path(args.storage, "--storage")
                root = args.storage / args.out.resolve().name
            self.probe = Probe(args.address)
        self.path = root.resolve()

    def connect(self) -> None:
        if self.probe is not None:
            connect(self.address, self.probe)

    def run(self, trials: Sequence[Trial], label: str) -> Outcome:
        """Run the unfinished ``trials`` with a progress bar; the caller writes its summary from ``finished``."""
        self.path.mkdir(parents=True, exist_ok=True)
        bar = make_bar(len(trials), label, "trial", initial=len(finished(self.path, trials)))

        def on_done(name: str, record: dict | None) -> None:
            bar.set_postfix_str(f"{name}: {'done' if record else 'FAILED'}")
            bar.update(1)

        try:
            return run_trials(trials, self.path, self.workers, self.address, on_done)
        finally:
            bar.close()
