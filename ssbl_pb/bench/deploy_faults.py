"""Faults injected into deploy against the virtual Pepper (``tools/bench_deploy.py --faults``): each fault's exit code
and stop times from the virtual Pepper's own log, the walker faults (whole approaches scored by the smallest true
clearance), and a soak (memory and late ticks held at the slot)."""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..deploy.frames import Frames
from ..deploy.log import LOG, SUMMARY
from ..deploy.loop import DeployLoop, DeployParams, Setup
from ..deploy.naoqi import IDENTITY, NaoqiRobot, import_qi
from ..deploy.perceive import Perception
from ..deploy.watchdog import RETRY_S
from ..params import RobotParams
from ..virtual.pepper import load_log
from .deploy import lockstep_approach, run_approach, start_deploy, stop_times, virtual_pepper, wait_moving

# fault -> (``virtual.walkers`` kind, scenario, seed): runs where the person does walk into the robot's way (the
# member out of view beside its path, the stranger ahead of it), and an entry without the range guard
WALKER_FAULTS = {"member_steps_in": ("member", "mixed", 500_000), "stranger_steps_in": ("stranger", "default", 11)}
FAULTS = ("robot_killed", "camera_frozen", "odometry_frozen", "robot_frozen", "sigint", "sigterm", "sighup",
          "policy_exception", "deploy_killed", "watchdog_stop_hangs", *WALKER_FAULTS)
WATCHED = ("deploy_killed", "watchdog_stop_hangs")  # deploy killed: the watchdog on the robot stops the base


def _rss_mb(pid: int) -> float | None:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return None


def walker_fault(fault: str, folder: Path, seed: int | None = None, policy: str = "vector", lockstep: bool = False,
                 duration: float = 60.0, scenario: str | None = None) -> dict[str, Any]:
    """A walker fault (``WALKER_FAULTS``; its scenario and seed unless given): one approach with that scripted
    person (in lockstep, or over qi), its outcome, when the walker acted, and the smallest true clearance to anyone
    (an intimate-zone entry fails)."""
    kind, default_scenario, default_seed = WALKER_FAULTS[fault]
    seed = default_seed if seed is None else seed
    res = (lockstep_approach if lockstep else run_approach)(folder, seed, policy, scenario or default_scenario,
                                                            duration, walker=kind)
    _, states, _ = load_log(folder / "virtual_pepper.jsonl")
    walkers = next((s["walkers"] for s in reversed(states) if s.get("walkers")), [{}])
    keys = ("exit_code", "outcome", "true_min_clearance_m", "true_success", "range_guard_interventions")
    return {"fault": fault, "seed": seed, **{k: res.get(k) for k in keys},
            "walker_acted_at": walkers[0].get("triggered_at")}


class NotInjected(RuntimeError):
    """Deploy ended before its base moved (on a loaded machine: a frame late before the fault), so the fault was
    never injected: nothing was measured."""


def run_fault(fault: str, folder: Path, seed: int = 11, policy: str = "straight", stale: float = 0.5,
              hang_stops: int = 1, vp_extra: tuple[str, ...] = (), lockstep: bool = False, walker_run: int = 0
              ) -> dict[str, Any]:
    """Inject ``fault`` (one of ``FAULTS``) once the base moves; exit code, exit and stop times. A walker fault
    is ``walker_fault`` with the shipped policy (``lockstep``: in this process).

    ``policy_exception`` runs the loop in a fresh interpreter (a policy that raises) over qi; ``deploy_killed``
    kills deploy with SIGKILL (the virtual Pepper's watchdog stops the base); ``watchdog_stop_hangs`` does the same
    with a virtual Pepper that leaves the ``hang_stops`` stopMove calls after the kill unanswered for 2 s, doing
    nothing (the watchdog must send again until the base reads still); ``sighup`` is the ssh connection to deploy's
    machine dropping; ``odometry_frozen`` freezes the virtual Pepper's odometry (SIGUSR2); ``robot_frozen`` stops
    the robot process (SIGSTOP) until deploy exits. ``stale``: deploy's staleness limit (tests on a loaded machine
    raise it, so that late frames do not end a run before its fault). ``vp_extra``: more virtual Pepper flags."""
    if fault not in FAULTS:
        raise ValueError(f"fault {fault!r}: expected one of {FAULTS}")
    if fault in WALKER_FAULTS:  # its own seed, or the ``walker_run``-th after it
        return walker_fault(fault, folder, WALKER_FAULTS[fault][2] + walker_run, lockstep=lockstep)
    folder.mkdir(parents=True, exist_ok=True)
    vp_log = folder / "virtual_pepper.jsonl"
    out: dict[str, Any] = {"fault": fault}
    with virtual_pepper(vp_log, seed, "default", *vp_extra) as (vp, url):
        if fault == "policy_exception":  # in a fresh interpreter, as deploy runs: in the benchmark's own
            # process (scipy, matplotlib and the approaches' imports loaded) its first frames arrived > 0.5 s late
            code = ("import json, sys; from pathlib import Path; "
                    "from ssbl_pb.bench.deploy_faults import _policy_exception; "
                    "print(json.dumps(_policy_exception(sys.argv[1], Path(sys.argv[2]), float(sys.argv[3]))))")
            res = subprocess.run([sys.executable, "-c", code, url, str(vp_log), str(stale)], capture_output=True,
                                 text=True, timeout=120)
            if res.returncode != 0:
                raise RuntimeError(f"policy_exception fault: exit {res.returncode}: {res.stderr.strip()[-500:]}")
            return {**out, **json.loads(res.stdout.strip().splitlines()[-1])}
        proc = start_deploy(url, folder / "deploy", policy, "--duration", "60", "--stale", str(stale))
        try:
            wait_moving(vp_log)
        except RuntimeError:
            proc.kill()
            said = proc.communicate()[1][-500:]
            raise NotInjected(f"{fault}: the base did not move; deploy said {said!r}") from None
        if fault == "watchdog_stop_hangs":  # armed now: a stall before the kill must not spend them
            hang_stops_now(url, hang_stops)
        t_event = time.time()
        target = {"robot_killed": (vp, signal.SIGKILL), "camera_frozen": (vp, signal.SIGUSR1),
                  "odometry_frozen": (vp, signal.SIGUSR2), "robot_frozen": (vp, signal.SIGSTOP),
                  "sigint": (proc, signal.SIGINT), "sigterm": (proc, signal.SIGTERM), "sighup": (proc, signal.SIGHUP),
                  "deploy_killed": (proc, signal.SIGKILL), "watchdog_stop_hangs": (proc, signal.SIGKILL)}[fault]
        target[0].send_signal(target[1])
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            out["hung"] = True
        out.update(exit_code=proc.returncode, exit_s=time.time() - t_event, stderr=err.strip().splitlines()[-1:])
        if fault == "robot_frozen":
            vp.send_signal(signal.SIGCONT)
        # let the log show what the base did next: braking from 0.35 m/s takes 1.2 s, after a retry period per hung stop
        settle = time.time() + 4.0 + (RETRY_S * hang_stops if fault == "watchdog_stop_hangs" else 0.0)
        while fault != "robot_killed" and time.time() < settle:
            time.sleep(0.25)
            if stop_times(vp_log, t_event)["standstill_s"] is not None:
                time.sleep(0.5)  # and that it stays still
                break
    if fault != "robot_killed":
        out.update(stop_times(vp_log, t_event))
        calls = load_log(vp_log)[2]
        out["watchdog"] = [c["line"] for c in calls if c["kind"] == "watchdog" and c["wall"] >= t_event]
        out["stop_calls"] = sum(c.get("call") == "stopMove" for c in calls if c["wall"] >= t_event)
        out["hung_stops"] = sum(c.get("call") == "stopMove_hung" for c in calls if c["wall"] >= t_event)
    return out


def hang_stops_now(url: str, n: int) -> None:
    """Make the virtual Pepper at ``url`` leave its next ``n`` stopMove calls unanswered (``--hang-stops``, from
    now on)."""
    session = import_qi().Session()
    session.connect(url, _async=True).value(5000)
    try:
        session.service(IDENTITY, _async=True).value(5000).hangStops(n, _async=True).value(5000)
    finally:
        session.close()


def _policy_exception(url: str, vp_log: Path, stale: float) -> dict[str, Any]:
    """The loop in this process over qi, with a policy that raises after a second of driving."""
    class Raising:
        calls, raised_at = 0, None

        def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
                    ) -> tuple[Any, Any]:
            self.calls += 1
            if self.calls > 15:
                self.raised_at = time.time()
                raise RuntimeError("injected policy fault")
            return np.array([1.0, 0.0]), None

    robot = NaoqiRobot(url, RobotParams())
    policy = Raising()
    loop = DeployLoop(Setup(robot, policy, Perception(robot, time.monotonic, "colour"), Frames()),
                      DeployParams(status_s=0, stale_s=stale))
    switch = sys.getswitchinterval()
    sys.setswitchinterval(0.001)  # as deploy runs (``__main__._warm_up``): with Python's 5 ms the frame grabber
    try:  # waited on the detector thread and the loop stopped on a stale frame before the policy raised
        with contextlib.suppress(RuntimeError):
            loop.run()
    finally:
        sys.setswitchinterval(switch)
    time.sleep(1.5)
    t_event = policy.raised_at
    return {"exit_code": loop.exit_code, "outcome": loop.outcome, "raised": t_event is not None,
            **(stop_times(vp_log, t_event) if t_event else {})}


def rss_series(pid: int, seconds: float, every: float = 5.0) -> list[tuple[float, float]]:
    """(elapsed s, RSS MB) of a process sampled every ``every`` s for ``seconds`` (or until it exits)."""
    out, t0 = [], time.monotonic()
    while time.monotonic() - t0 < seconds:
        rss = _rss_mb(pid)
        if rss is None:
            break
        out.append((time.monotonic() - t0, rss))
        time.sleep(every)
    return out


def soak(folder: Path, seconds: float, seed: int = 500_000, policy: str = "vector") -> dict[str, Any]:
    """Deploy held at the slot (``--continue-after-success``) for ``seconds``: its memory (RSS sampled every 5 s
    from the loop's first tick) and late ticks. Growth compares the mean RSS of the last fifth of the run with
    that of the second fifth (the first is warm-up: the tracker, the log and the allocator settling)."""
    folder.mkdir(parents=True, exist_ok=True)
    with virtual_pepper(folder / "virtual_pepper.jsonl", seed) as (_, url):
        proc = start_deploy(url, folder / "deploy", policy, "--continue-after-success", "--duration", str(seconds))
        end = time.monotonic() + 120.0
        while not (folder / "deploy" / LOG).is_file() and proc.poll() is None and time.monotonic() < end:
            time.sleep(0.2)
        rss = rss_series(proc.pid, seconds + 30.0)
        proc.communicate(timeout=120)
    summary = json.loads((folder / "deploy" / SUMMARY).read_text())
    early = [m for t, m in rss if 0.2 * seconds <= t < 0.4 * seconds]
    late = [m for t, m in rss if 0.8 * seconds <= t <= seconds]
    growth = (sum(late) / len(late)) / (sum(early) / len(early)) - 1.0 if early and late else None
    return {"seconds": seconds, "exit_code": proc.returncode, "rss_mb": rss, "rss_growth": growth,
            **{k: summary.get(k) for k in ("outcome", "ticks", "tick_ms_median", "tick_ms_p99",
                                           "estimate_age_ms_median", "late_tick_fraction")}}
