"""One episode step by step, as the policy saw it and as it was (``tools/trace_episode.py``): for reading why an
episode failed, which an evaluation's one row per episode does not tell.

Each step's row: the robot's pose, whether the policy drove (not perception's search or looks), what the policy asked
(after its smoothing, before its shield) and what the shield let through with the rules that changed it, the true
place and the perceived one with the robot's distance to each, how many members there are and how many perception
holds, and which side of the robot the observation's nearest member lies on. Two counts
summarise the indecision seen in front of a group (docs/benchmarks_movenet.md, "Ending short of a place it knows"):
the lateral reversals (the policy asking hard left, then hard right, or back) and the swaps of the nearest member
from one side to the other.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..agents.metrics import failure_kind
from ..agents.rollout import EpisodeResult, run_episode
from ..core import observation as ob
from ..core.shield import rule_names
from ..files import atomic_write_all, write_json
from .evaluation import Setup, outcome
from .report import write_csv

HARD = 0.5  # of the top speed: a lateral request at least this large counts toward a reversal (``reversals``)


class _Watched:
    """A policy whose last observation and action are kept (the shield's record, ``shield.last``, passes through)."""

    def __init__(self, policy: Any) -> None:
        self.policy, self.obs, self.action = policy, None, None

    @property
    def shield(self) -> Any:
        return getattr(self.policy, "shield", None)

    def reset(self) -> None:
        if hasattr(self.policy, "reset"):
            self.policy.reset()

    def predict(self, observation: Any, **kwargs: Any) -> tuple[np.ndarray, Any]:
        self.obs = np.array(observation, dtype=float, copy=True).ravel()
        action, state = self.policy.predict(observation, **kwargs)
        self.action = np.asarray(action, dtype=float).ravel()
        return action, state


def _state(env: Any) -> dict[str, Any]:
    """The batch-of-one engine's state now: the robot, the true group and what perception holds."""
    sim = env.unwrapped.sim
    g, p = sim.groups_state, sim.perceived
    n = int(g.count[0])
    seen = p is not None and bool(p.known[0])
    return {"pose": sim.pose[0].copy(), "members": g.pos[0, :n].copy(), "place": sim.slot[0].copy(),
            "seen_members": None if p is None else p.pos[0, :int(p.count[0])].copy(),
            "seen_place": p.slot[0].copy() if seen else np.full(2, math.nan)}


def _row(before: dict[str, Any], watched: _Watched, driven: bool, dt: float, k: int) -> dict[str, Any]:
    last = getattr(watched.shield, "last", None)
    asked = watched.action if last is None else np.asarray(last.before, dtype=float).ravel()
    rules = 0 if last is None else int(np.asarray(last.rules).ravel()[0])
    x, y, yaw = before["pose"][:3]
    members, _ = ob.decode_members(watched.obs)
    near = members[np.argmin(np.hypot(*members.T))] if len(members) else None
    seen = before["seen_members"]
    return {"t_s": round(k * dt, 3), "x_m": float(x), "y_m": float(y), "yaw_deg": math.degrees(float(yaw)),
            "driven": int(driven), "asked_forward": float(asked[0]), "asked_left": float(asked[1]),
            "command_forward": float(watched.action[0]), "command_left": float(watched.action[1]),
            "shield_rules": "+".join(rule_names(rules)),
            "place_x_m": float(before["place"][0]), "place_y_m": float(before["place"][1]),
            "place_distance_m": float(np.hypot(*(before["place"] - (x, y)))),
            "seen_place_x_m": float(before["seen_place"][0]), "seen_place_y_m": float(before["seen_place"][1]),
            "seen_place_distance_m": float(np.hypot(*(before["seen_place"] - (x, y)))),
            "members": len(before["members"]), "members_seen": -1 if seen is None else len(seen),
            "nearest_member_side": ("left" if near[1] >= 0 else "right") if near is not None else "",
            "nearest_member_distance_m": float(np.hypot(*near)) if near is not None else math.nan}


def reversals(rows: list[dict[str, Any]]) -> int:
    """How often the policy, driving, asked for a hard lateral move (``HARD``) opposite to its previous hard one."""
    side, n = 0.0, 0
    for r in rows:
        if r["driven"] and abs(r["asked_left"]) >= HARD:
            s = math.copysign(1.0, r["asked_left"])
            n += side != 0.0 and s != side
            side = s
    return n


def side_swaps(rows: list[dict[str, Any]]) -> int:
    """How often the observation's nearest member changed from one side of the robot to the other."""
    sides = [r["nearest_member_side"] for r in rows if r["nearest_member_side"]]
    return sum(a != b for a, b in zip(sides, sides[1:], strict=False))


def trace(setup: Setup, seed: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]], EpisodeResult, float]:
    """Play episode ``seed``; returns its rows (one per step), the states before each step (for ``plot_trace``),
    the episode's result (``run_episode``) and the env's slot tolerance (m)."""
    env, policy = setup()
    tolerance = env.unwrapped.task.slot_tolerance
    watched = _Watched(policy)
    rows: list[dict[str, Any]] = []
    states: list[dict[str, Any]] = []

    def on_step(e: Any) -> None:
        if states:  # the step just taken, from the state before it
            rows.append(_row(states[-1], watched, bool(e.unwrapped.sim.driven[0]), e.unwrapped.dt, len(rows)))
        states.append(_state(e))

    try:
        result = run_episode(env, watched, seed, on_step=on_step)
    finally:
        env.close()
    return rows, states[:-1], result, tolerance


def summary_of(setup: Setup, seed: int, rows: list[dict[str, Any]], result: EpisodeResult,
               tolerance: float) -> dict[str, Any]:
    m = result.metrics
    out = {"policy": setup.policy, "scenario": setup.scenario, "seed": seed,
           "env": dict(setup.env_kwargs), "outcome": outcome(m), "steps": len(rows),
           "episode_time_s": m["episode_time_s"], "shield_intervention_rate": m["shield_intervention_rate"],
           "lateral_reversals": reversals(rows), "nearest_member_side_swaps": side_swaps(rows)}
    if "perceived_slot_error_m" in m:
        out["failure"] = failure_kind(bool(m["success"]), bool(m["violation"]), m["perceived_slot_error_m"],
                                      m["perceived_place_distance_m"], tolerance) or "none"
        out["perceived_place_error_m"] = m["perceived_slot_error_m"]
    return out


def plot_trace(path: Path, rows: list[dict[str, Any]], states: list[dict[str, Any]], title: str) -> None:
    """From above (the path; true members as circles, perceived ones as crosses, at the start, the middle and the
    end), and over time (what the policy asked and what it got, the distances to both places, the members rule)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, time) = plt.subplots(1, 2, figsize=(13, 6), gridspec_kw={"width_ratios": [1, 1.3]})
    path_xy = np.array([[r["x_m"], r["y_m"]] for r in rows])
    top.plot(path_xy[:, 0], path_xy[:, 1], "k-", lw=1)
    for k, colour, label in ((0, "tab:blue", "start"), (len(states) // 2, "tab:orange", "middle"),
                             (len(states) - 1, "tab:red", "end")):
        s = states[k]
        top.plot(*s["members"].T, "o", mfc="none", mec=colour, ms=13, label=f"members ({label})")
        if s["seen_members"] is not None and len(s["seen_members"]):
            top.plot(*s["seen_members"].T, "x", color=colour, ms=8)
        top.plot(*s["place"], "P", color=colour, ms=10)
        top.plot(*s["seen_place"], "*", color=colour, ms=12)
        top.plot(*s["pose"][:2], "s", color=colour, ms=6)
    top.set_aspect("equal")
    top.set_title("o true members, x perceived; P true place, * perceived", fontsize=9)
    top.legend(fontsize=7, loc="best")
    t = np.array([r["t_s"] for r in rows])
    for key, colour, style, label in (("asked_forward", "tab:blue", "--", "asked forward"),
                                      ("asked_left", "tab:orange", "--", "asked left"),
                                      ("command_forward", "tab:blue", "-", "commanded forward"),
                                      ("command_left", "tab:orange", "-", "commanded left"),
                                      ("place_distance_m", "tab:purple", "-", "to the true place (m)"),
                                      ("seen_place_distance_m", "tab:red", "-", "to the perceived place (m)")):
        time.plot(t, [r[key] for r in rows], style, color=colour, lw=1, label=label)
    held = [1.05 if "members" in r["shield_rules"] else math.nan for r in rows]
    time.plot(t, held, "|", color="tab:green", ms=4, label="shield: members rule")
    time.set_xlabel("time (s)")
    time.grid(alpha=0.3)
    time.legend(fontsize=7, loc="upper right")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_trace(out: Path, setup: Setup, seed: int) -> dict[str, Any]:
    """Trace episode ``seed`` into ``out``: ``trace.csv``, ``trace.png`` and ``summary.json`` (written together)."""
    rows, states, result, tolerance = trace(setup, seed)
    summary = summary_of(setup, seed, rows, result, tolerance)
    title = (f"{setup.policy} on {setup.scenario}, seed {seed}: {summary['outcome']}; lateral reversals "
             f"{summary['lateral_reversals']}, nearest member side swaps {summary['nearest_member_side_swaps']}")
    atomic_write_all({out / "trace.csv": lambda p: write_csv(p, rows),
                      out / "trace.png": lambda p: plot_trace(p, rows, states, title),
                      out / "summary.json": lambda p: write_json(p, summary)})
    return summary
