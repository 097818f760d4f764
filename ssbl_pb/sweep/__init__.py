"""Sweeps: training configurations x seeds, each trained and evaluated on held-out episodes, on a local process
pool or (given an address) as Ray Tune trials on a cluster; resumable; summarised per configuration.

- ``spec``: the SPEC.yaml format and its validation; trial names.
- ``trial``: the sweep's trial (train, then evaluate) and what it returns.
- ``runner``: ``run_trials`` for any list of trials (the sweep's, or e.g. Table I's rows), result files, resume.
- ``pool`` / ``ray_runner``: the local pool and the Ray Tune runner (ray is imported only there).
- ``summary``: summary.csv / summary.md / summary.png / trials.csv.
"""

from .dispatch import run_trials
from .runner import Outcome, Trial, TrialsFailed, finished
from .spec import SpecError, SweepSpec, load_spec
from .trial import METRICS, EvalSpec, TrainEvalTrial, trials_for

__all__ = ["METRICS", "EvalSpec", "Outcome", "SpecError", "SweepSpec", "TrainEvalTrial", "Trial", "TrialsFailed",
           "finished", "load_spec", "run_trials", "trials_for"]
