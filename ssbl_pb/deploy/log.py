"""The deploy record: ``DIR/log.jsonl`` (one tick per line, flushed, so a crash loses at most one tick),
``DIR/run.json`` (the run's settings, written first) and ``DIR/summary.json`` (written at the end).

A tick row holds ``t`` (s since start), ``state``, the odometry pose ``odom_x/odom_y/odom_yaw`` and the command
sent ``cmd_vx/cmd_vy/cmd_wz`` under the column names ``tools/identify_dynamics.py`` reads (the log is a
dynamics log as it stands), the measured body velocity ``vel``, the room- and map-frame poses, the policy's
command before the clamp ``cmd_policy``, the tracked humans (odometry frame, with covariance and facing), the group
estimate, ``estimate_age_ms``, ``tick_ms`` (tick start to command sent), ``late``, NAOqi events, and on policy
ticks ``shield``: what the policy's safety shield changed (the action before and after it, the rules that acted,
``cmd_before`` the body command it replaced), null where it changed nothing; ``ranges``, how many range returns
the robot gave (null without range sensors) and ``range_guard``, what braking for them changed (the command before
and after, the nearest return and its clearance; ``deploy.guards``), null where nothing. The summary's
``shield_intervention_rate`` is the share of policy ticks the shield changed (those whose command the robot
was sent: not a look, a confirmation or the hold at the place, which replace it), ``range_guard_rate`` the share of
ticks with range returns the range guard changed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..calib.dynamics_log import CMD, POSE
from ..files import write_json

LOG, RUN, SUMMARY, PATHS = "log.jsonl", "run.json", "summary.json", "paths.png"
POLICY_STATES = ("approach", "dock", "joined")  # the loop's states that send the policy's command (``DeployLoop``)


def _clean(value: Any) -> Any:
    """JSON-ready: numpy to lists/floats, non-finite floats to None."""
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    return value


def dynamics_columns(odom_pose: np.ndarray, cmd: np.ndarray) -> dict[str, float]:
    """The columns ``calib.dynamics_log.read_log`` needs, from the odometry pose and the command sent."""
    return {**dict(zip(POSE, (float(v) for v in odom_pose), strict=True)),
            **dict(zip(CMD, (float(v) for v in cmd), strict=True))}


class RunLog:
    """Appends tick rows to ``DIR/log.jsonl`` and keeps what the summary needs (a few floats per tick)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self._fh = open(self.folder / LOG, "a", buffering=1)  # line-buffered: each row reaches the file
        self.tick_ms: list[float] = []
        self.age_ms: list[float] = []
        self.late = 0
        self.min_clearance = math.inf
        self.policy_ticks = 0  # ticks the policy acted in (a ``shield`` entry), and those the shield changed
        self.shielded = 0
        self.ranged_ticks = 0  # ticks with range returns, and those the range guard changed
        self.range_guarded = 0

    def write(self, row: dict[str, Any]) -> None:
        self._fh.write(json.dumps(_clean(row)) + "\n")
        self._fh.flush()
        self.tick_ms.append(float(row["tick_ms"]))
        if row.get("estimate_age_ms") is not None:
            self.age_ms.append(float(row["estimate_age_ms"]))
        self.late += bool(row.get("late"))
        if row.get("min_clearance_m") is not None:
            self.min_clearance = min(self.min_clearance, float(row["min_clearance_m"]))
        if "shield" in row and row.get("state") in POLICY_STATES:
            self.policy_ticks += 1
            self.shielded += row["shield"] is not None
        if row.get("ranges") is not None:
            self.ranged_ticks += 1
            self.range_guarded += row.get("range_guard") is not None

    def summary(self, outcome: str, exit_code: int, message: str, extra: dict[str, Any]) -> dict[str, Any]:
        def pct(xs: list[float], q: float) -> float | None:
            return float(np.percentile(xs, q)) if xs else None

        return _clean({"outcome": outcome, "exit_code": exit_code, "message": message, "ticks": len(self.tick_ms),
                       "tick_ms_median": pct(self.tick_ms, 50), "tick_ms_p99": pct(self.tick_ms, 99),
                       "estimate_age_ms_median": pct(self.age_ms, 50),
                       "late_tick_fraction": self.late / len(self.tick_ms) if self.tick_ms else None,
                       "min_human_distance_m": self.min_clearance if math.isfinite(self.min_clearance) else None,
                       "policy_ticks": self.policy_ticks, "shield_interventions": self.shielded,
                       "shield_intervention_rate": self.shielded / self.policy_ticks if self.policy_ticks else None,
                       "range_ticks": self.ranged_ticks, "range_guard_interventions": self.range_guarded,
                       "range_guard_rate": self.range_guarded / self.ranged_ticks if self.ranged_ticks else None,
                       **extra})

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()


def write_run(folder: Path, info: dict[str, Any]) -> None:
    write_json(Path(folder) / RUN, _clean(info))


def write_summary(folder: Path, summary: dict[str, Any]) -> None:
    write_json(Path(folder) / SUMMARY, summary)


def read_log(folder: str | Path) -> list[dict[str, Any]]:
    """The tick rows of a deploy log (a last line cut short by a crash is skipped)."""
    rows = []
    for line in (Path(folder) / LOG).read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows
