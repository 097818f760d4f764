"""Trials as Ray Tune trials on an existing cluster; imported only when an address is given (ray[tune] 2.60,
the ``sweep`` extra).

Each trial is a function trainable of one CPU that runs the same ``runner.run_task`` as the local pool, into
``ROOT/trials/NAME/`` (ROOT: a path every node sees), and reports its metrics with ``tune.report``. Tune's own
experiment state goes to ``ROOT/tune/sweep-KEY/`` (KEY: a hash of the trial names); running the same trials again
restores it (``Tuner.restore(..., resume_errored=True)``) and Tune reruns what had not finished, while a trial
whose ``result.json`` exists returns at once.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import logging
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..errors import UserError
from .runner import RESULT, Trial, _normal, run_task, trial_dir

POLL_S = 2.0  # how often the driver looks for finished trials (progress only)
CONNECT_S = 3.0  # TCP connect to the head: a refused or unreachable address fails here, without Ray
PROBE_S = 20.0  # a child process joining the cluster (importing Ray takes a few seconds of it)
PROBE = """import logging, os, sys, threading
stop = threading.Timer(float(sys.argv[2]), os._exit, (124,))
stop.daemon = True
stop.start()
import ray
ray.init(address=sys.argv[1], logging_level=logging.ERROR)
ray.shutdown()
"""  # the child ends itself after PROBE_S, even when its parent is gone


class Probe:
    """Whether a Ray cluster answers at ``address``, found out in a child process started at once (``ray.init``
    waits minutes on a port that answers but is no Ray head); ``wait()`` raises a UserError within ``PROBE_S`` of
    the start. Start it early: the child works while the caller checks its other inputs."""

    def __init__(self, address: str) -> None:
        self.address = address
        if importlib.util.find_spec("ray") is None:
            raise UserError(f"--address {address}: Ray is not installed; install the sweep extra "
                            f"(pip install -e '.[sweep]', ray[tune]==2.60.0)")
        if address != "auto":
            host, port = parse_address(address)
            try:
                socket.create_connection((host, port), timeout=CONNECT_S).close()
            except OSError as exc:
                raise UserError(f"--address {address}: no Ray cluster answers there ({exc.strerror or exc}); start "
                                f"one with `ray start --head --port {port}` (docs/scale-out.md)") from exc
        self.lines: list[str] = []
        self.refused = threading.Event()  # the head answered and refused our token: no point waiting longer
        self.deadline = time.monotonic() + PROBE_S + 5.0
        self.proc = subprocess.Popen([sys.executable, "-c", PROBE, address, str(PROBE_S)], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stderr or ():
            self.lines.append(line)
            if "InvalidAuthToken" in line or "Unauthenticated" in line:
                self.refused.set()

    def wait(self) -> None:
        while self.proc.poll() is None and time.monotonic() < self.deadline:
            if self.refused.wait(0.1):
                break
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.refused.is_set():
            raise UserError(f"--address {self.address}: the Ray cluster refused this client's token; set "
                            f"RAY_AUTH_MODE=token and RAY_AUTH_TOKEN to the cluster's token (`ray get-auth-token` on "
                            f"the head; docs/scale-out.md)")
        if self.proc.returncode == 0:
            return
        if self.proc.returncode == 124 or self.proc.returncode < 0:
            raise UserError(f"--address {self.address}: no Ray cluster answered within {PROBE_S:.0f} s (is it the "
                            f"head's GCS port, 6379 by default?)")
        lines = [ln for ln in self.lines if ln.strip()]
        why = " ".join(lines[-1].split())[:300] if lines else f"exit code {self.proc.returncode}"
        raise UserError(f"--address {self.address}: cannot join the Ray cluster: {why}")


def connect(address: str, probe: Probe | None = None) -> None:
    """Join the Ray cluster at ``address`` (HOST:PORT of the head, or ``auto``) after ``probe`` (started here if
    not given) found it. Never starts a cluster: ``ray.init()`` without an address would quietly start one."""
    if probe is None and "ray" in sys.modules and sys.modules["ray"].is_initialized():
        return  # joined already (the tool probes and joins before it runs the trials)
    (probe or Probe(address)).wait()
    import ray

    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)


def parse_address(address: str) -> tuple[str, int]:
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise UserError(f"--address {address!r}: expected HOST:PORT of the Ray head (port 6379 by default) or auto")
    return host, int(port)


def run_on_ray(pending: Sequence[Trial], trials: Sequence[Trial], root: Path, address: str, workers: int | None,
               done: Callable[[str, dict[str, Any] | None], None]) -> dict[str, str]:
    """Run ``pending`` (of all ``trials``) as Tune trials; returns name -> error text of those that failed."""
    connect(address)
    from ray import tune

    by_name = {t.name: t for t in trials}
    key = hashlib.sha1("\n".join(sorted(by_name)).encode()).hexdigest()[:10]
    storage, exp = root / "tune", root / "tune" / f"sweep-{key}"
    trainable = tune.with_resources(tune.with_parameters(_ray_trial, trials=by_name, root=str(root)), {"cpu": 1})
    if tune.Tuner.can_restore(str(exp)):
        tuner = tune.Tuner.restore(str(exp), trainable, resume_errored=True)
    else:
        tuner = tune.Tuner(
            trainable, param_space={"trial": tune.grid_search([t.name for t in pending])},
            tune_config=tune.TuneConfig(max_concurrent_trials=workers, reuse_actors=True,
                                        trial_dirname_creator=_dirname),
            run_config=tune.RunConfig(name=exp.name, storage_path=str(storage), verbose=0,
                                      failure_config=tune.FailureConfig(max_failures=0)))
    stop = threading.Event()
    watcher = threading.Thread(target=_watch, args=(pending, root, done, stop), daemon=True)
    watcher.start()
    try:
        results = tuner.fit()
    finally:
        stop.set()
        watcher.join()
    failed: dict[str, str] = {}
    for res in results:
        name = res.config["trial"]
        if res.error is not None and not (trial_dir(root, name) / RESULT).is_file():
            failed[name] = str(res.error)
            done(name, None)
    return failed


def _watch(pending: Sequence[Trial], root: Path, done: Callable[[str, dict[str, Any] | None], None],
           stop: threading.Event) -> None:
    """Report trials as their result files appear (the driver's progress bar)."""
    left = {t.name for t in pending}
    while left:
        last = stop.wait(POLL_S)
        for name in sorted(left):
            path = trial_dir(root, name) / RESULT
            if path.is_file():
                try:
                    record = json.loads(path.read_text())
                except ValueError:
                    continue
                left.discard(name)
                done(name, record)
        if last:
            return


def _dirname(trial: Any) -> str:
    return f"{trial.config['trial']}-{trial.trial_id}"[:150]


def _ray_trial(config: dict[str, Any], trials: dict[str, Trial], root: str) -> None:
    """One Tune trial: the stored result if this trial already finished, else ``run_task`` on this node."""
    import ray
    from ray import tune

    task = trials[config["trial"]]
    path = trial_dir(Path(root), task.name) / RESULT
    record = None
    if path.is_file():
        try:
            record = json.loads(path.read_text())
        except ValueError:
            record = None
        if record is not None and record.get("task") != _normal(task.definition()):
            record = None
    if record is None:
        record = run_task(task, Path(root), ray.get_runtime_context().get_node_id())
    tune.report({k: v for k, v in record["result"].items() if isinstance(v, int | float) and not isinstance(v, bool)})
