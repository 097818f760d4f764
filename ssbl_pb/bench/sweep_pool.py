"""Local pool throughput: the same trials run with one worker and with N, alternately, trials per minute each
(tools/bench_sweep.py). CPU seconds of the workers are measured too, so that a slow run on a busy machine shows
as such (same CPU, longer wall time)."""

from __future__ import annotations

import os
import resource
import shutil
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..files import make_stage_dir
from ..sweep.dispatch import run_trials
from ..sweep.spec import SweepSpec


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def bench_pool(spec: SweepSpec, workers: int, repeats: int, scratch: Path,
               note: Callable[[str], None] = print) -> dict[str, Any]:
    """Run ``spec``'s trials ``repeats`` times with 1 worker and with ``workers`` (order alternating), each time
    into a fresh folder under ``scratch`` (removed after); the ratio is of median trials per minute."""
    trials = spec.trials()
    runs = []
    for r in range(repeats):
        for w in ((1, workers) if r % 2 == 0 else (workers, 1)):
            folder = make_stage_dir(scratch, f".bench-sweep-{w}-")
            try:
                load0, cpu0, t0 = os.getloadavg()[0], _children_cpu(), time.perf_counter()
                run_trials(trials, folder, workers=w).raise_failures(folder)
                wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
            finally:
                shutil.rmtree(folder, ignore_errors=True)
            runs.append({"workers": w, "repeat": r, "wall_s": round(wall, 1), "worker_cpu_s": round(cpu, 1),
                         "trials_per_min": round(60 * len(trials) / wall, 2),
                         "load_1min_before": round(load0, 2), "load_1min_after": round(os.getloadavg()[0], 2)})
            note(f"{w} worker(s), repeat {r + 1}/{repeats}: {wall:.0f} s, {runs[-1]['trials_per_min']} trials/min "
                 f"(machine load {load0:.1f} -> {os.getloadavg()[0]:.1f})")
    median = {w: statistics.median(x["trials_per_min"] for x in runs if x["workers"] == w) for w in (1, workers)}
    cpu = {w: statistics.median(x["worker_cpu_s"] for x in runs if x["workers"] == w) for w in (1, workers)}
    return {"spec": str(spec.path), "trials": len(trials), "workers": workers, "repeats": repeats,
            "cores": os.cpu_count(), "runs": runs, "trials_per_min_1": median[1],
            f"trials_per_min_{workers}": median[workers], "speedup": round(median[workers] / median[1], 2),
            # what the speed-up would be with a free core per worker: one worker's CPU seconds over the pool's
            # per worker (the extra workers' start-up is the difference); an estimate, for a busy machine
            "cpu_bound_speedup": round(cpu[1] / (cpu[workers] / workers), 2)}


def markdown(r: dict[str, Any], command: str) -> str:
    n = r["workers"]
    lines = [f"# Local pool: {n} workers vs 1", "", f"`{command}`", "",
             f"{r['trials']} trials of `{r['spec']}`, {r['repeats']} repeats per setting, {r['cores']} cores; "
             f"median trials per minute: 1 worker {r['trials_per_min_1']}, {n} workers "
             f"{r[f'trials_per_min_{n}']}: **{r['speedup']}x** (target for 2 workers on 2 cores: >= 1.7x). With a free "
             f"core per worker (estimated from CPU seconds: one worker's over the pool's per worker): "
             f"{r['cpu_bound_speedup']}x.", "",
             "| workers | repeat | wall s | worker CPU s | trials/min | load before | load after |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {x['workers']} | {x['repeat'] + 1} | {x['wall_s']} | {x['worker_cpu_s']} | {x['trials_per_min']} | "
              f"{x['load_1min_before']} | {x['load_1min_after']} |" for x in r["runs"]]
    return "\n".join(lines) + "\n"
