"""Deploy against the virtual Pepper in subprocesses, as a user runs it (or in lockstep in this process): approaches
scored by the simulator's ground truth, the harness the faults share (``deploy_faults``) and the benchmark's
Markdown. Used by ``tools/bench_deploy.py`` and the tests.

Times: "stop commanded" is when the virtual base received the stop (its command became zero); "standstill" is
when it stood still (it decelerates at Pepper's 0.3 m/s^2, about 1.2 s from full speed, as the real base does);
"robot time" counts the simulated base's own seconds (its ``t``), which stand still while the robot process is
stopped (``robot_frozen``): the time the base drove on under its last command.

The virtual Pepper serves the ``SSBLWatchdog`` itself (as a Pepper on which the user started the watchdog), so
every run has one and ``deploy_killed``/``watchdog_stop_hangs`` need no separate watchdog process: the hosted one
is the arrangement users get, and its lines are in the virtual Pepper's log (``kind: watchdog``).
The walker faults (``WALKER_FAULTS``: a member stepping toward the robot's path out of view, a stranger never seen
stepping into it; ``virtual.walkers``) are whole approaches scored by the smallest true clearance to anyone.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..agents.trained import PolicyView, policy_groups, policy_view
from ..core.task import TaskParams
from ..deploy.frames import Frames, load_room
from ..deploy.log import LOG, SUMMARY, RunLog, write_run, write_summary
from ..deploy.loop import DeployLoop, DeployParams, Setup
from ..deploy.perceive import Perception, detector_for
from ..deploy.policy import load_policy
from ..params import RobotParams, SocialParams
from ..virtual.pepper import load_log, state_row, write_room_map
from ..virtual.robot import DETECTOR, SimClock, SimRobot
from ..virtual.walkers import make_walker
from .perception_errors import analyse_folder, markdown_table, pool, summarise
from .perception_errors_plot import plot


def _module(name: str, *args: str) -> list[str]:
    return [sys.executable, "-m", name, *args]


def _first_line(proc: subprocess.Popen, timeout: float) -> str:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        line = proc.stdout.readline() if proc.stdout else ""
        if line.strip():
            return line.strip()
        if proc.poll() is not None:
            raise RuntimeError(f"{proc.args}: exited with {proc.returncode} before saying anything")
    raise RuntimeError(f"{proc.args}: said nothing within {timeout} s")


@contextlib.contextmanager
def virtual_pepper(log: Path, seed: int = 0, scenario: str = "default", *extra: str
                   ) -> Iterator[tuple[subprocess.Popen, str]]:
    """A virtual Pepper on a free loopback port: (process, url); terminated (and continued, if stopped) on exit.
    Its people are box proxies (the colour detector's chain) unless ``extra`` says ``--appearance body``."""
    look = () if "--appearance" in extra else ("--appearance", "proxy")
    proc = subprocess.Popen(_module("ssbl_pb.virtual", "--listen", "tcp://127.0.0.1:0", "--seed",
                                    str(seed), "--scenario", scenario, "--log", str(log), *look, *extra),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:  # (stdin /dev/null: with a job-control shell's stdin it was seen not to step at all)
        url = _first_line(proc, 60.0).split()[-1]
        yield proc, url
    finally:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGCONT)
                proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def start_deploy(url: str, folder: Path, policy: str = "vector", *extra: str) -> subprocess.Popen:
    """Deploy as a user starts it against the virtual Pepper (its detector chosen by ``--detector auto``, its
    watchdog the one the virtual Pepper serves)."""
    return subprocess.Popen(_module("ssbl_pb.deploy", "--url", url, "--policy", policy, "--log-dir", str(folder),
                                    "--quiet", *extra),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_moving(log: Path, timeout: float = 60.0, speed: float = 0.15) -> float:
    """Wall time at which the virtual base first moves faster than ``speed`` (m/s)."""
    end = time.time() + timeout
    while time.time() < end:
        if log.is_file():
            for line in log.read_text().splitlines()[-50:]:
                with contextlib.suppress(json.JSONDecodeError):
                    row = json.loads(line)
                    if row.get("kind") == "state" and math.hypot(*row["vel"][:2]) > speed:
                        return float(row["wall"])
        time.sleep(0.1)
    raise RuntimeError(f"{log}: the base did not move within {timeout} s")


def stop_times(log: Path, t_event: float) -> dict[str, float | None]:
    """Seconds from ``t_event`` (wall) until the base's command was zero, and until it stood still, for good; and
    the command's zero in robot time (``stop_commanded_robot_s``: the base's own seconds since its last state
    at or before ``t_event``)."""
    _, states, _ = load_log(log)
    after = [s for s in states if s["wall"] >= t_event]
    before = [s for s in states if s["wall"] < t_event]
    t0 = before[-1]["t"] if before else after[0]["t"] if after else 0.0
    out: dict[str, float | None] = {"stop_commanded_s": None, "standstill_s": None, "stop_commanded_robot_s": None}
    for key, still in (("stop_commanded_s", lambda s: not any(s["cmd"])),
                       ("standstill_s", lambda s: max(abs(v) for v in s["vel"]) < 1e-3)):
        for i, s in enumerate(after):
            if all(still(r) for r in after[i:]):
                out[key] = s["wall"] - t_event
                if key == "stop_commanded_s":
                    out["stop_commanded_robot_s"] = s["t"] - t0
                break
    return out


def truth_score(vp_log: Path, deploy_dir: Path, task: TaskParams | None = None) -> dict[str, Any]:
    """The simulator's success rule at the deploy's last tick (slot distance, heading, speed) and the smallest
    true clearance to any member over the run (an intimate-zone entry fails it)."""
    task = task or TaskParams()
    _, states, _ = load_log(vp_log)
    rows = [json.loads(line) for line in (deploy_dir / LOG).read_text().splitlines() if line.strip()]
    if not rows or not states:
        return {"true_success": False, "reason": "no log"}
    end = rows[-1]["wall"]
    during = [s for s in states if rows[0]["wall"] - 0.1 <= s["wall"] <= end + 0.1] or states
    last = min(states, key=lambda s: abs(s["wall"] - end))
    (x, y, yaw), (cx, cy) = last["pose"], last["centre"]
    heading = abs(math.degrees(math.remainder(math.atan2(cy - y, cx - x) - yaw, 2 * math.pi)))
    slot = math.dist(last["pose"][:2], last["slot"])
    clearance = min(s["clearance"] for s in during)
    speed = math.hypot(*last["vel"][:2])
    ok = (slot < task.slot_tolerance and heading < task.heading_tolerance_deg and speed < task.stop_speed
          and clearance >= task.intimate_zone)
    return {"true_success": ok, "true_slot_m": slot, "true_heading_deg": heading, "true_speed": speed,
            "true_min_clearance_m": clearance, "collision": any(s["collision"] for s in during)}


def _map_flags(proc: subprocess.Popen, timeout: float = 60.0) -> tuple[str, ...]:
    """Deploy's ``--map ... --start-pose ...`` from a virtual Pepper started with ``--write-map``."""
    while True:
        line = _first_line(proc, timeout)
        if line.startswith("map:"):
            return tuple(line.split()[1:])


def run_approach(folder: Path, seed: int, policy: str = "vector", scenario: str = "default",
                 duration: float = 90.0, groups: str | None = None, detector: str = "auto",
                 room_map: bool = True, walker: str | None = None, appearance: str = "proxy") -> dict[str, Any]:
    """One approach against a fresh virtual Pepper: the deploy summary plus the ground-truth score. ``groups``:
    the group model of both (default: each one's own, the policy's); ``detector``: deploy's ``--detector``
    (``auto``: the one the virtual Pepper names for its people's look); ``room_map``: deploy gets the room's map
    (``--map``, ``--start-pose``), as a user who mapped the room runs it; ``walker``: the virtual Pepper's
    ``--walker``; ``appearance``: its ``--appearance`` (box proxies by default: the colour chain)."""
    folder.mkdir(parents=True, exist_ok=True)
    vp_log = folder / "virtual_pepper.jsonl"
    flag = () if groups is None else ("--groups", groups)
    written = ("--write-map", str(folder / "map")) if room_map else ()
    scripted = () if walker is None else ("--walker", walker)
    with virtual_pepper(vp_log, seed, scenario, *flag, *written, *scripted, "--appearance", appearance) as (vp, url):
        on_map = _map_flags(vp) if room_map else ()
        proc = start_deploy(url, folder / "deploy", policy, "--duration", str(duration), "--detector", detector,
                            *flag, *on_map)
        _, err = proc.communicate(timeout=duration + 120)
    summary = json.loads((folder / "deploy" / SUMMARY).read_text())
    return {"seed": seed, "exit_code": proc.returncode, **summary, **truth_score(vp_log, folder / "deploy"),
            "stderr_tail": err.strip().splitlines()[-1:] if err.strip() else []}


def lockstep_approach(folder: Path, seed: int, policy: Any = "vector", scenario: str = "default",
                      duration: float = 90.0, groups: str | None = None, fps: float = 15.0,
                      detector: str = "auto", room_map: bool = True, walker: str | None = None,
                      appearance: str = "proxy") -> dict[str, Any]:
    """One approach in this process, deterministic (no qi): deploy's loop on a ``SimRobot`` in lockstep
    (``SimClock``, the camera at ``fps``, perception inline), writing the two logs ``run_approach`` leaves
    (``folder/deploy/log.jsonl``, ``folder/virtual_pepper.jsonl``); ``wall`` in both is the simulated time, and
    each tick's ground truth is logged at its tick's time. ``policy``: a spec as deploy's ``--policy`` or a
    policy object (``predict``); ``detector``, ``room_map``, ``walker`` and ``appearance`` as ``run_approach``.
    Returns the outcome and the ground-truth score."""
    spec = isinstance(policy, str)
    groups = groups or (policy_groups(policy) if spec else "calibrated")
    robot_params, social, task, params = RobotParams(), SocialParams(), TaskParams(), DeployParams(
        duration_s=duration, status_s=0.0)
    pol = load_policy(policy, robot_params, social, task, params.stop_distance) if spec else policy
    view = policy_view(policy) if spec and hasattr(pol, "model") else PolicyView()
    (folder / "deploy").mkdir(parents=True, exist_ok=True)
    (folder / "deploy" / LOG).unlink(missing_ok=True)  # RunLog appends
    vp_log = folder / "virtual_pepper.jsonl"
    robot = SimRobot(scenario, seed, groups=groups, appearance=appearance)
    if walker is not None:
        robot.add_walker(make_walker(walker))
    clock = SimClock(robot, fps)
    frames = Frames()
    if room_map:
        room_yaml, start = write_room_map(folder / "map", robot)
        frames = Frames(load_room(room_yaml), start)
    with open(vp_log, "w") as fh:
        fh.write(json.dumps({"kind": "start", "wall": robot.t, "start_pose": robot.start_pose.tolist(),
                             **robot.info}) + "\n")

        class Log(RunLog):  # each tick row at simulated time, and the truth beside it
            def write(self, row: dict[str, Any]) -> None:
                row = {**row, "wall": robot.t, "tick_ms": 0.0, "odom_ms": 0.0}
                super().write(row)
                fh.write(json.dumps(state_row(robot, robot.t)) + "\n")

        log = Log(folder / "deploy")
        perception = Perception(robot, clock.now, detector_for(detector, robot), robot_params,
                                social=social, threaded=False)
        loop = DeployLoop(Setup(robot, pol, perception, frames, robot_params, social, task, groups,
                                **dataclasses.asdict(view)),
                          params, log, now=clock.now, sleep=clock.sleep)
        try:
            outcome, message = loop.run()
        finally:
            log.close()
            robot.close()
    summary = log.summary(outcome, loop.exit_code, message, {})
    write_summary(folder / "deploy", summary)
    write_run(folder / "deploy", {"policy": policy if spec else type(policy).__name__, "groups": groups,
                                  "lockstep": True, "detector": detector_for(detector, robot),
                                  "appearance": appearance, **frames.info()})
    return {"seed": seed, **summary, **truth_score(vp_log, folder / "deploy", task)}


def perception_report(folders: list[Path], policy: str = "vector", figure: Path | None = None
                      ) -> tuple[list[dict[str, Any] | None], dict[str, Any] | None]:
    """Perception's errors (``perception_errors``) of each run folder (None where it has no logs) and pooled
    over them, the policy's action difference with the policy ``policy``; ``figure``: the pooled figure."""
    pol = load_policy(policy, RobotParams(), SocialParams(), TaskParams(), DeployParams().stop_distance)
    view = policy_view(policy) if hasattr(pol, "model") else PolicyView()
    parts = [analyse_folder(f, pol, view=view)
             if (f / "deploy" / LOG).is_file() and (f / "virtual_pepper.jsonl").is_file() else None for f in folders]
    found = [p for p in parts if p is not None]
    if not found:
        return [None] * len(folders), None
    if figure is not None:
        plot(pool(found), figure, f"{len(found)} runs, policy {policy}: deploy's perception against the virtual "
                                  f"Pepper's ground truth")
    return [None if p is None else summarise(p) for p in parts], summarise(pool(found))


def environment() -> dict[str, Any]:
    """Where a benchmark ran: cores and the load average (the machine is shared)."""
    return {"cpus": os.cpu_count(), "loadavg": list(os.getloadavg()), "python": sys.version.split()[0]}


def markdown(res: dict[str, Any]) -> str:
    """The benchmark's section for docs/benchmarks.md."""
    out = []
    runs = res.get("approaches", [])
    if runs:
        ok = sum(r.get("true_success", False) for r in runs)
        claimed = sum(r.get("outcome") == "success" for r in runs)
        intimate = sum(r.get("true_min_clearance_m", 9) < TaskParams.intimate_zone for r in runs)
        # a run that ended on a fault before its first tick has no clearance
        cleared = [r["true_min_clearance_m"] for r in runs if r.get("true_min_clearance_m") is not None]

        def med(key: str) -> float:
            vals = sorted(r[key] for r in runs if r.get(key) is not None)
            return vals[len(vals) // 2] if vals else float("nan")  # e.g. no estimate age: nobody ever tracked

        p99 = max(r["tick_ms_p99"] for r in runs if r.get("tick_ms_p99") is not None)
        ticks = sum(r.get("policy_ticks") or 0 for r in runs)
        shielded = sum(r.get("shield_interventions") or 0 for r in runs)
        ranged = sum(r.get("range_ticks") or 0 for r in runs)
        range_guarded = sum(r.get("range_guard_interventions") or 0 for r in runs)
        look, detector = res.get("appearance") or "proxy", res.get("detector") or "auto"
        if detector == "auto":

            detector = f"auto: {DETECTOR[look]}"
        out += [f"**Approaches** ({len(runs)} seeded runs, seeds {runs[0]['seed']}-{runs[-1]['seed']}, scenario "
                f"`{res['scenario']}`, {res.get('groups') or 'calibrated'} groups, policy `{res['policy']}`, people "
                f"drawn as {look}, detector `{detector}`"
                f"{'; lockstep, in process: tick times are not measured' if res.get('lockstep') else ''}): "
                f"success by the simulator's own rule and ground truth in **{ok}/{len(runs)}** (deploy claimed "
                f"{claimed}); intimate-zone entries: **{intimate}**; "
                f"smallest true clearance {min(cleared, default=float('nan')):.2f} m.",
                f"Control tick (start to command sent): median of run medians {med('tick_ms_median'):.1f} ms, worst "
                f"run p99 {p99:.1f} ms; estimate age median {med('estimate_age_ms_median'):.0f} ms. The policy's "
                f"shield changed its command in {100 * shielded / max(ticks, 1):.1f} % of {ticks} policy ticks; the "
                f"range guard (the base's lasers and sonars) in {100 * range_guarded / max(ranged, 1):.1f} % of "
                f"{ranged} ticks.", "",
                "| seed | outcome | true success | slot (m) | heading (deg) | min clearance (m) | tick median / p99 "
                "(ms) | estimate age (ms) | shield (%) |", "|---|---|---|---|---|---|---|---|---|"]
        for r in runs:
            out.append(f"| {r['seed']} | {r.get('outcome')} | {'yes' if r.get('true_success') else 'no'} | "
                       f"{r.get('true_slot_m', float('nan')):.2f} | {r.get('true_heading_deg', float('nan')):.0f} | "
                       f"{r.get('true_min_clearance_m', float('nan')):.2f} | {r.get('tick_ms_median') or 0:.1f} / "
                       f"{r.get('tick_ms_p99') or 0:.1f} | {r.get('estimate_age_ms_median') or 0:.0f} | "
                       f"{100 * (r.get('shield_intervention_rate') or 0):.0f} |")
        out.append("")
    if res.get("perception"):
        per = res["perception"]
        pos, ids, miss = per["position_error_m"], per["ids_per_member"], per["missed"]
        figure = f" Figure: `{res['perception_figure']}`." if res.get("perception_figure") else ""
        out += [f"**Perception against ground truth** (the same runs, every tick; `ssbl_pb/deploy/"
                f"perception_errors.py`): detected members' position error median "
                f"{pos['seen']['median'] or 0:.2f} m (p90 {pos['seen']['p90'] or 0:.2f} m), remembered ones "
                f"{pos['remembered']['median'] or 0:.2f} m; members without any track "
                f"{100 * (miss['rate'] or 0):.0f} % of member-ticks ({miss['out_of_view']} out of view, "
                f"{miss['edge']} at the image's edge, {miss['occluded']} occluded, {miss['in_view']} in view); "
                f"{per['duplicated_member_ticks']} member-ticks tracked twice; {ids['mean'] or 0:.2f} track ids per "
                f"member (max {ids['max']}); the policy network's action moved by "
                f"{per['action_delta']['mean'] or 0:.3f} on average (|delta| of its 2-D action, perceived vs true "
                f"observation; {per['action_delta_still']['mean'] or 0:.3f} with the members' velocities zeroed in "
                f"both).{figure}", "",
                markdown_table(res.get("approaches", []), per)]
    faults = res.get("faults", [])
    if faults:
        out += ["**Faults** (each injected once the base moved; times from the virtual Pepper's own log; robot time: "
                "the simulated base's own seconds, which stand still while its process is stopped; the walker faults "
                "are whole approaches, scored by the smallest true clearance to anyone):", "",
                "| fault | exit code | process exit (s) | stop commanded (s) | stop commanded, robot time (s) | "
                "standstill (s) | true min clearance (m) |", "|" + "---|" * 7]
        for f in faults:
            cells = ["-" if f.get(k) is None else f"{f[k]:.2f}"
                     for k in ("exit_s", "stop_commanded_s", "stop_commanded_robot_s", "standstill_s",
                               "true_min_clearance_m")]
            name = f"{f['fault']} (seed {f['seed']})" if "seed" in f else f["fault"]
            code = "not injected" if f.get("not_injected") else f["exit_code"]
            out.append(f"| {name} | {code} | " + " | ".join(cells) + " |")
        out.append("")
        out += walker_summary(faults)
    if res.get("soak"):
        s = res["soak"]
        growth = "-" if s["rss_growth"] is None else f"{100 * s['rss_growth']:+.1f} %"
        out.append(f"**Soak** ({s['seconds']:.0f} s at 10 Hz, held at the slot): memory growth {growth} "
                   f"(RSS {s['rss_mb'][0][1]:.0f} -> {s['rss_mb'][-1][1]:.0f} MB), late ticks "
                   f"{100 * (s['late_tick_fraction'] or 0):.2f} % of {s['ticks']}, tick median / p99 "
                   f"{s['tick_ms_median']:.1f} / {s['tick_ms_p99']:.1f} ms.")
    env = res.get("environment", {})
    out.append(f"\nMachine: {env.get('cpus')} cores, load average {env.get('loadavg')} at the start (shared).")
    return "\n".join(out) + "\n"


def walker_summary(faults: list[dict[str, Any]], intimate: float = TaskParams.intimate_zone) -> list[str]:
    """One line per walker fault run more than once: runs, how many the walker acted in, intimate-zone entries
    (true clearance below ``intimate``) and the smallest clearance."""
    lines = []
    for name in dict.fromkeys(f["fault"] for f in faults if "seed" in f):
        runs = [f for f in faults if f["fault"] == name]
        if len(runs) < 2:
            continue
        clear = [f["true_min_clearance_m"] for f in runs if f.get("true_min_clearance_m") is not None]
        acted = sum(f.get("walker_acted_at") is not None for f in runs)
        lines.append(f"`{name}` over {len(runs)} runs (seeds {runs[0]['seed']}-{runs[-1]['seed']}; the walker acted in "
                     f"{acted}): intimate-zone entries **{sum(c < intimate for c in clear)}**, smallest true "
                     f"clearance {min(clear, default=float('nan')):.2f} m.")
    return lines + ([""] if lines else [])
