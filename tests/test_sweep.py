"""Sweeps: spec validation and names, the local pool (failures, dead workers, orphans, resume), a tiny real sweep
killed and resumed, and the same sweep on a two-node Ray cluster in a private network namespace."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ssbl_pb.errors import UserError
from ssbl_pb.sweep import SpecError, load_spec, run_trials
from ssbl_pb.sweep.spec import MAX_NAME, config_name

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "tests" / "sweep_specs"
TOOL = [sys.executable, str(ROOT / "tools" / "sweep.py")]
BASE = str(ROOT / "configs" / "vector_ff.yaml")


@dataclasses.dataclass(frozen=True)
class Echo:
    """A trial that returns value**2 (or raises, dies, sleeps); every call is logged in ROOT/calls.txt."""

    name: str
    value: float
    mode: str = "ok"

    def definition(self) -> dict:
        return {"value": self.value}

    def __call__(self, trial_dir: Path) -> dict:
        trial_dir.mkdir(parents=True, exist_ok=True)
        with open(trial_dir.parents[1] / "calls.txt", "a") as f:
            f.write(self.name + "\n")
        if self.mode == "raise":
            raise ValueError(f"bad value {self.value}")
        if self.mode == "die":
            os._exit(7)
        if self.mode == "sleep":
            (trial_dir / "pid").write_text(str(os.getpid()))
            time.sleep(120)
        if self.mode == "defer":  # as training does: a signal stops it at its next safe point and is re-raised
            from ssbl_pb.cli import DeferredSignals

            with DeferredSignals() as signals:
                (trial_dir / "pid").write_text(str(os.getpid()))
                deadline = time.time() + 120
                while signals.signum is None and time.time() < deadline:
                    time.sleep(0.05)
                signals.raise_if_signalled()
        return {"square": self.value ** 2}


def _spec(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return path


def test_summary_intervals_stay_where_the_quantities_can_be(tmp_path):
    """Two seeds that disagree: the Student t interval of a time or a distance would reach below 0 and is cut at
    0 (the mean kept), a rate's stays in 0-1, the return's is left as it is; the table's note says so."""
    from ssbl_pb.sweep import summary
    from ssbl_pb.sweep.trial import METRICS

    spec = load_spec(SPECS / "tiny.yaml")
    values = [{m: 0.0 for m in METRICS} | {"success_rate": 1.0, "mean_return": -1.0},
              {m: 3.0 for m in METRICS} | {"success_rate": 0.0, "collision_rate": 1.0, "violation_rate": 1.0}]
    trials = [t for t in spec.trials() if t.group == "learning_rate=0.001"]
    records = {t.name: {"result": v} for t, v in zip(trials, values, strict=True)}
    row = summary.rows(spec, records)[0]
    assert row["seeds"] == 2
    for m in METRICS:
        mean, low, high = (row[f"{m}_{k}"] for k in ("mean", "ci_low", "ci_high"))
        if m == "mean_return":  # 1 +- 12.7 * 2.83 / sqrt(2): no bound
            assert low < -20 and high > 20 and mean == 1.0
        elif m in summary.RATES:
            assert 0.0 <= low < mean < high <= 1.0
        else:  # 1.5 +- 12.7 * 2.12 / sqrt(2) = 1.5 +- 19.1
            assert (low, mean) == (0.0, 1.5) and high == pytest.approx(1.5 + 19.06, abs=0.01), m
    text = summary.markdown(spec, summary.rows(spec, records), 2, "python tools/sweep.py tiny.yaml")
    assert "| learning_rate=0.001 | 2 | 50.0 [0.2, 99.8] | 1.00 [-24.41, 26.41] | 50.0 [0.2, 99.8] |" in text
    assert text.count("1.50 [0.00, 20.56]") == 2 and text.count("1.500 [0.000, 20.559]") == 3
    assert "is cut at 0" in text


def test_spec_grid_product_names_and_resolved_configs(tmp_path):
    spec = load_spec(_spec(tmp_path, f"""
base: {BASE}
grid:
  ppo.learning_rate: [0.001, 0.0003]
  reward.w_prox: [1, 3]
seeds: [5, 7]
set: {{total_steps: 4096, ppo.net_arch: [32, 32]}}
eval: {{episodes: 20, scenario: mixed}}
"""))
    assert list(spec.configs) == ["learning_rate=0.001,w_prox=1", "learning_rate=0.001,w_prox=3",
                                  "learning_rate=0.0003,w_prox=1", "learning_rate=0.0003,w_prox=3"]
    trials = spec.trials()
    assert [t.name for t in trials[:2]] == ["learning_rate=0.001,w_prox=1,seed=5",
                                            "learning_rate=0.001,w_prox=1,seed=7"]
    last = trials[-1].config
    assert (last["seed"], last["total_steps"], last["ppo"]["learning_rate"], last["reward"]["w_prox"]) == (7, 4096,
                                                                                                         0.0003, 3)
    assert last["ppo"]["net_arch"] == [32, 32] and last["reward"]["w_smooth"] == 0.05  # the base file's value kept
    assert trials[0].evaluation.episodes == 20 and trials[0].evaluation.scenario == "mixed"
    assert trials[0].evaluation.seed == 500_000  # held-out seeds by default


def test_trials_for_named_configs():
    from ssbl_pb.sweep import EvalSpec, trials_for
    from ssbl_pb.training.config import load_config

    rows = {"ff": load_config(BASE), "lstm": load_config(BASE, {"policy": "lstm"})}
    trials = trials_for(rows, [0, 1], EvalSpec(episodes=10))
    assert [t.name for t in trials] == ["ff,seed=0", "ff,seed=1", "lstm,seed=0", "lstm,seed=1"]
    assert trials[3].group == "lstm" and trials[3].config["policy"] == "lstm" and trials[3].config["seed"] == 1
    assert load_config(None, trials[3].config) == load_config(BASE, {"policy": "lstm", "seed": 1})


def test_names_short_unique_and_safe():
    assert config_name({}) == "base"
    assert config_name({"ppo.net_arch": [64, 64], "env.x": "a/b c"}) == "ppo.net_arch=64-64,env.x=a-b-c"
    long = config_name({"reward.w": list(range(60))})
    assert len(long) == MAX_NAME and long != config_name({"reward.w": list(range(61))})


@pytest.mark.parametrize("body, fragment", [
    ("grids: {{reward.w_smooth: [1]}}\nseeds: [0]", "unknown key(s) ['grids']"),
    ("grid: {{reward.w_smooth: [1]}}", "seeds: missing"),
    ("seeds: [0, 0]", "seeds = [0, 0]"),
    ("seeds: [0]\ngrid: {{reward.w_bogus: [1]}}", "grid key 'reward.w_bogus'"),
    ("seeds: [0]\ngrid: {{ppo.lr: [1]}}", "grid key 'ppo.lr'"),
    ("seeds: [0]\ngrid: {{learning_rate: [1]}}", "grid key 'learning_rate'"),
    ("seeds: [0]\ngrid: {{env.bogus: [1]}}", "grid.env.bogus = 1"),
    ("seeds: [0]\ngrid: {{ppo.learning_rate: [0.001, 5]}}", "grid.ppo.learning_rate = 5"),
    ("seeds: [0]\ngrid: {{ppo.learning_rate: []}}", "non-empty list"),
    ("seeds: [0]\ngrid: {{ppo.learning_rate: [0.1, 0.1]}}", "listed twice"),
    ("seeds: [0]\nset: {{seed: 3}}", "seeds list sets the seed"),
    ("seeds: [0]\nset: {{total_steps: 10}}\ngrid: {{total_steps: [20]}}", "set twice"),
    ("seeds: [0]\nset: {{scenario: bogus}}", "scenario 'bogus'"),
    ("seeds: [0]\neval: {{episode: 3}}", "eval: unknown key(s) ['episode']"),
    ("seeds: [0]\neval: {{episodes: 0}}", "eval.episodes = 0"),
    ("seeds: [0]\neval: {{model: best}}\nset: {{total_steps: 1000}}", "eval.model = 'best'"),
])
def test_bad_specs_name_the_key(tmp_path, body, fragment):
    with pytest.raises(SpecError) as err:
        load_spec(_spec(tmp_path, f"base: {BASE}\n" + body.format()))
    assert fragment in str(err.value) and "spec.yaml" in str(err.value)


def test_base_resolved_beside_the_spec(tmp_path):
    shutil.copy(BASE, tmp_path / "mine.yaml")
    assert load_spec(_spec(tmp_path, "base: mine.yaml\nseeds: [1]")).base == (tmp_path / "mine.yaml").resolve()
    with pytest.raises(SpecError, match="base 'none.yaml': file not found"):
        load_spec(_spec(tmp_path, "base: none.yaml\nseeds: [1]"))


def _calls(root: Path) -> list[str]:
    return sorted((root / "calls.txt").read_text().split())


def test_pool_reports_failures_and_reruns_only_unfinished(tmp_path):
    trials = [Echo("a", 2.0), Echo("b", 3.0, "raise"), Echo("c", 4.0, "die"), Echo("d", 5.0)]
    seen = []
    out = run_trials(trials, tmp_path, workers=2, on_done=lambda n, r: seen.append((n, r is not None)))
    assert {n: r["result"]["square"] for n, r in out.records.items()} == {"a": 4.0, "d": 25.0}
    assert "ValueError: bad value 3.0" in out.failed["b"]
    assert "worker process died (exit code 7)" in out.failed["c"]
    assert sorted(seen) == [("a", True), ("b", False), ("c", False), ("d", True)]
    assert "ValueError: bad value 3.0" in (tmp_path / "logs" / "b.log").read_text()  # the traceback is kept
    assert json.loads((tmp_path / "trials" / "a" / "result.json").read_text())["task"] == {"value": 2.0}
    with pytest.raises(RuntimeError, match="2 trial"):
        out.raise_failures(tmp_path)
    # the same trials again, fixed: only the two that failed run
    (tmp_path / "calls.txt").unlink()
    again = run_trials([Echo("a", 2.0), Echo("b", 3.0), Echo("c", 4.0), Echo("d", 5.0)], tmp_path, workers=2)
    assert _calls(tmp_path) == ["b", "c"] and not again.failed
    assert {n: r["result"]["square"] for n, r in again.records.items()} == {"a": 4.0, "b": 9.0, "c": 16.0, "d": 25.0}
    # a stored result of another definition is refused, not mixed in
    with pytest.raises(UserError, match="trial a was run with another definition"):
        run_trials([Echo("a", 2.5)], tmp_path)
    with pytest.raises(UserError, match="used twice"):
        run_trials([Echo("x", 1.0), Echo("x", 2.0)], tmp_path)
    with pytest.raises(UserError, match="trial name '../x'"):
        run_trials([Echo("../x", 1.0)], tmp_path)


def _gone(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return True
    return "State:\tZ" in status


def test_workers_exit_when_the_sweep_is_killed(tmp_path):
    code = (f"import sys; sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
            "from pathlib import Path\nfrom test_sweep import Echo\nfrom ssbl_pb.sweep import run_trials\n"
            f"run_trials([Echo('s', 1.0, 'sleep')], Path({str(tmp_path)!r}), workers=1)\n")
    parent = subprocess.Popen([sys.executable, "-c", code])
    pid_file = tmp_path / "trials" / "s" / "pid"
    deadline = time.time() + 60
    while time.time() < deadline and not pid_file.exists():
        time.sleep(0.1)
    worker = int(pid_file.read_text())
    parent.send_signal(signal.SIGKILL)  # the parent alone: its worker must not keep running the trial
    parent.wait()
    deadline = time.time() + 10
    while time.time() < deadline and not _gone(worker):
        time.sleep(0.1)
    assert _gone(worker)


def test_ctrl_c_while_a_worker_starts_is_one_line_from_the_parent(tmp_path):
    """Ctrl-C to the process group (as a terminal sends it) while a worker is still starting (importing): the
    worker ignores it from its first instruction and is stopped; only the parent reports, in one line."""
    marker = tmp_path / "importing"
    script = tmp_path / "slow_start.py"
    script.write_text(
        "import sys, time\nfrom pathlib import Path\n"
        f"sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
        "if __name__ == '__mp_main__':  # a spawned worker imports this file first: hold it there\n"
        "    Path(sys.argv[1]).write_text('x')\n    time.sleep(60)\n"
        "if __name__ == '__main__':\n"
        "    import signal\n    signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "    from test_sweep import Echo\n    from ssbl_pb.cli import run\n    from ssbl_pb.sweep import run_trials\n"
        "    run(lambda argv: run_trials([Echo('a', 1.0)], Path(sys.argv[2]), workers=1) and 0)\n")
    proc = subprocess.Popen([sys.executable, str(script), str(marker), str(tmp_path / "root")],
                            start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not marker.exists() and proc.poll() is None:
        time.sleep(0.05)
    assert marker.exists(), proc.communicate()
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and err.splitlines() == ["interrupted (Ctrl-C)"], err
    assert not list((tmp_path / "root").glob("trials/*/result.json"))


@pytest.mark.parametrize("sig, code, line", [(signal.SIGINT, 130, "interrupted (Ctrl-C)"),
                                             (signal.SIGTERM, 143, "terminated (SIGTERM)")])
def test_a_stopped_sweep_is_one_line_from_the_parent_not_its_workers_tracebacks(tmp_path, sig, code, line):
    """Ctrl-C or SIGTERM while the workers run trials that stop at a safe point on a signal (training does): the
    parent stops them, and they leave quietly (no traceback of the signal re-raised in them)."""
    script = tmp_path / "sweep_two.py"
    script.write_text(
        "import sys\nfrom pathlib import Path\n"
        f"sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
        "if __name__ == '__main__':\n"
        "    from test_sweep import Echo\n    from ssbl_pb.cli import run\n    from ssbl_pb.sweep import run_trials\n"
        "    trials = [Echo('a', 1.0, 'defer'), Echo('b', 2.0, 'defer')]\n"
        "    run(lambda argv: run_trials(trials, Path(sys.argv[1]), workers=2) and 0)\n")
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path / "root")], start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pids = [tmp_path / "root" / "trials" / n / "pid" for n in "ab"]
    deadline = time.time() + 90
    while time.time() < deadline and not all(p.exists() for p in pids) and proc.poll() is None:
        time.sleep(0.05)
    assert all(p.exists() for p in pids), proc.communicate()
    os.killpg(proc.pid, sig)  # as a terminal's Ctrl-C (the process group); the workers have sessions of their own
    out, err = proc.communicate(timeout=60)
    time.sleep(0.5)  # a worker's last words would come after its parent's
    workers = [int(p.read_text()) for p in pids]
    deadline = time.time() + 10
    while time.time() < deadline and not all(_gone(w) for w in workers):
        time.sleep(0.1)
    assert proc.returncode == code and err.splitlines() == [line], err
    assert all(_gone(w) for w in workers)


# -- a real sweep: 2 configurations x 2 seeds of 1024 training steps, evaluated on 3 held-out episodes -------------
def _sweep(cmd: list[str], trials: Path) -> dict:
    """Start the sweep, SIGKILL its process group once a trial has finished, start it again and run to the end."""
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while time.time() < deadline and proc.poll() is None and not list(trials.glob("*/result.json")):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    at_kill = {p.parent.name: p.stat().st_mtime_ns for p in trials.glob("*/result.json")}
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=400)
    return {"at_kill": at_kill, "returncode": res.returncode, "stderr": res.stderr}


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "sweep"
    info = _sweep([*TOOL, str(SPECS / "tiny.yaml"), "--out", str(out), "--workers", "2"], out / "trials")
    return out, info


@pytest.mark.slow
def test_local_sweep_killed_and_resumed(local_sweep):
    out, info = local_sweep
    assert info["returncode"] == 0, info["stderr"][-3000:]
    assert 1 <= len(info["at_kill"]) < 4, info["at_kill"]  # killed mid-way
    for name, mtime in info["at_kill"].items():  # finished trials were kept, not run again
        assert (out / "trials" / name / "result.json").stat().st_mtime_ns == mtime
        assert (out / "logs" / f"{name}.log").read_text().count("\n== ") == 0
    names = sorted(p.name for p in (out / "trials").iterdir())
    assert names == ["learning_rate=0.001,seed=0", "learning_rate=0.001,seed=1", "learning_rate=0.003,seed=0",
                     "learning_rate=0.003,seed=1"]
    for name in names:
        assert (out / "trials" / name / "model.zip").is_file()
        assert (out / "trials" / name / "eval" / "summary.json").is_file()
    lines = (out / "summary.csv").read_text().splitlines()
    assert lines[0].startswith("config,ppo.learning_rate,seeds,success_rate_mean,success_rate_ci_low")
    assert [ln.split(",")[:3] for ln in lines[1:]] == [["learning_rate=0.001", "0.001", "2"],
                                                      ["learning_rate=0.003", "0.003", "2"]]
    ret = [float(ln.split(",")[lines[0].split(",").index("mean_return_mean")]) for ln in lines[1:]]
    assert ret[0] != ret[1]  # the two configurations did train differently
    trials = (out / "trials.csv").read_text().splitlines()
    assert len(trials) == 5 and all(",True," in t for t in trials[1:])
    assert "| learning_rate=0.003 | 2 |" in (out / "summary.md").read_text()
    assert (out / "summary.png").stat().st_size > 10_000
    # a third start has nothing left to do
    res = subprocess.run([*TOOL, str(SPECS / "tiny.yaml"), "--out", str(out), "--dry-run"], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0 and "4 finished" in res.stdout and "pending" not in res.stdout


def _namespace_problem() -> str | None:
    """Why a private network + PID namespace cannot be made here (None: it can)."""
    if not (shutil.which("unshare") and shutil.which("ip")):
        return "unshare or ip (util-linux, iproute2) is not installed"
    probe = subprocess.run(["unshare", "--net", "--pid", "--fork", "--mount-proc", "ip", "link", "set", "lo", "up"],
                           capture_output=True, text=True)
    return None if probe.returncode == 0 else f"unshare is not permitted here ({probe.stderr.strip()[:200]})"


@pytest.mark.slow
def test_two_node_ray_cluster_sweep_killed_resumed_same_summary(local_sweep, tmp_path):
    pytest.importorskip("ray", reason="Ray is not installed (the sweep extra: pip install -e '.[sweep]')")
    problem = _namespace_problem()
    if problem:
        pytest.skip(f"the two-node Ray test keeps all traffic on loopback in a private network namespace: {problem}")
    out, storage, report = tmp_path / "sweep", tmp_path / "storage", tmp_path / "report.json"
    subprocess.run(["unshare", "--net", "--pid", "--fork", "--mount-proc", sys.executable,
                    str(ROOT / "tests" / "ray_cluster.py"), str(SPECS / "tiny.yaml"), str(out), str(storage),
                    str(report)], check=True, timeout=900)
    info = json.loads(report.read_text())
    assert info["interfaces"].count("inet ") == 1 and "127.0.0.1" in info["interfaces"]  # loopback only
    assert info["wrong_token_exit"] == 2 and info["wrong_token_s"] < 30, info
    assert "refused this client's token" in info["wrong_token_stderr"].splitlines()[-1]
    assert info["first_exit"] is None and 1 <= len(info["finished_at_kill"]) < 4, info  # killed mid-way
    assert info["second_exit"] == 0, info["second_stderr"]
    trials = storage / "sweep" / "trials"
    for name, mtime in info["mtimes_at_kill"].items():
        assert (trials / name / "result.json").stat().st_mtime_ns == mtime
    records = [json.loads(p.read_text()) for p in sorted(trials.glob("*/result.json"))]
    assert len(records) == 4 and len({r["node_id"] for r in records}) == 2  # trials ran on both nodes
    assert (storage / "sweep" / "tune").is_dir()  # Tune's experiment state, restored on the second start
    assert (out / "summary.csv").read_text() == (local_sweep[0] / "summary.csv").read_text()


@pytest.mark.slow
def test_an_address_where_no_ray_head_answers_fails_within_30_s(tmp_path):
    pytest.importorskip("ray", reason="Ray is not installed (the sweep extra: pip install -e '.[sweep]')")
    import socket

    with socket.socket() as listener:  # accepts connections (the kernel does) but never speaks Ray's protocol
        listener.bind(("127.0.0.1", 0))
        listener.listen(8)
        address = f"127.0.0.1:{listener.getsockname()[1]}"
        t0 = time.time()
        res = subprocess.run([*TOOL, str(SPECS / "tiny.yaml"), "--out", str(tmp_path / "out"), "--address", address],
                             capture_output=True, text=True, timeout=120)
        took = time.time() - t0
    assert res.returncode == 2 and took < 30, (took, res.stderr)
    assert res.stderr.strip() == (f"error: --address {address}: no Ray cluster answered within 20 s (is it the "
                                  f"head's GCS port, 6379 by default?)")
    assert not (tmp_path / "out").exists()
