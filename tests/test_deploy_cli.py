"""Deploy's command-line tools as a user meets them: the deploy benchmark removes only what it wrote,
the virtual Pepper checks its port before it writes anything, the watchdog's help tells its real exit codes."""

from __future__ import annotations

import importlib.util
import json
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def _tool(*argv: str, timeout: float = 120) -> subprocess.CompletedProcess:
    cmd = [sys.executable, *argv] if argv[0] == "-m" else [sys.executable, str(ROOT / "tools" / argv[0]), *argv[1:]]
    return subprocess.run(cmd if argv[0] != "-m" else [sys.executable, *argv], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def test_bench_deploy_never_deletes_a_folder_it_did_not_write(tmp_path):
    mine = tmp_path / "results" / "bench"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("the user's\n")
    res = _tool("bench_deploy.py", "--runs", "0", "--faults", "none", "--soak", "0", "--out", str(mine))
    assert res.returncode == 2 and "did not write" in res.stderr, res.stderr
    assert (mine / "notes.txt").read_text() == "the user's\n"


def _bench_deploy_tool():
    spec = importlib.util.spec_from_file_location("_bench_deploy", ROOT / "tools" / "bench_deploy.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool


def test_bench_deploy_rerun_removes_exactly_the_entries_it_wrote(tmp_path, monkeypatch, capsys):
    """The marker lists what the tool wrote; a rerun removes those, never a user's ``run_old/`` or
    ``runtime_notes.txt`` beside them, and refuses to write over a ``run00`` it did not write."""
    from ssbl_pb.bench import deploy as bench

    def approach(folder, *_args, **_kw):  # as a lockstep run leaves its folder
        (folder / "deploy").mkdir(parents=True)
        (folder / "deploy" / "log.jsonl").write_text("{}\n")
        return {}

    monkeypatch.setattr(bench, "lockstep_approach", approach)
    monkeypatch.setattr(bench, "perception_report", lambda folders, *_a: ([{} for _ in folders], None))
    monkeypatch.setattr(bench, "markdown", lambda res: "")
    tool, out = _bench_deploy_tool(), tmp_path / "bench"
    argv = ["--lockstep", "--faults", "none", "--soak", "0", "--out", str(out)]
    assert tool.main(["--runs", "2", *argv]) == 0
    assert (out / "run01" / "deploy" / "log.jsonl").is_file()
    (out / "run_old").mkdir()  # the user's, added later
    (out / "runtime_notes.txt").write_text("kept\n")
    assert tool.main(["--runs", "0", *argv]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == [".bench_deploy", "run_old", "runtime_notes.txt"]
    (out / "run00").mkdir()  # not listed in the marker: never written over
    with pytest.raises(UserError, match="run00 exists and this tool did not write it"):
        tool.main(["--runs", "1", *argv])
    assert sorted(p.name for p in out.iterdir()) == [".bench_deploy", "run00", "run_old", "runtime_notes.txt"]


def test_bench_deploy_keeps_its_results_when_a_fault_cannot_be_injected(tmp_path, monkeypatch, capsys):
    """Deploy ending before the base moved (a late frame on a loaded machine) is tried once more in a fresh
    folder, then written as "not injected": the other faults' results are kept."""
    from ssbl_pb.bench import deploy_faults

    calls = []

    def fault(name, folder, **_kw):
        calls.append((name, sorted(p.name for p in folder.iterdir()) if folder.exists() else None))
        if name == "sigint":
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "half").write_text("x")
            raise deploy_faults.NotInjected("sigint: the base did not move")
        return {"fault": name, "exit_code": 143}

    monkeypatch.setattr(deploy_faults, "run_fault", fault)
    tool, out = _bench_deploy_tool(), tmp_path / "bench"
    assert tool.main(["--lockstep", "--runs", "0", "--faults", "sigint,sigterm", "--soak", "0", "--out", str(out)]) == 0
    assert calls == [("sigint", None), ("sigint", None), ("sigterm", None)]  # again, in a fresh folder
    res = json.loads(out.with_suffix(".json").read_text())
    assert res["faults"][1] == {"fault": "sigterm", "exit_code": 143}
    assert res["faults"][0]["exit_code"] is None and "did not move" in res["faults"][0]["not_injected"]
    assert "| sigint | not injected |" in out.with_suffix(".md").read_text()


def test_virtual_pepper_on_a_port_in_use_writes_no_map_and_says_so_in_one_line(tmp_path):
    pytest.importorskip("qi")
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    try:
        res = _tool("-m", "ssbl_pb.virtual", "--listen", f"tcp://127.0.0.1:{port}", "--write-map",
                    str(tmp_path / "map"))
    finally:
        server.close()
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert "cannot listen there" in lines[0] and "Address already in use" in lines[0]
    assert ".conan" not in lines[0] and ".hpp" not in lines[0]  # no library source path
    assert not (tmp_path / "map").exists()


def test_watchdog_help_states_its_exit_codes():
    res = _tool("-m", "ssbl_pb.deploy.watchdog", "--help")
    assert res.returncode == 0
    text = " ".join(res.stdout.split())
    assert "130 on Ctrl-C, 143 on SIGTERM" in text and "Exit: 0 on" not in text


def test_watchdog_alone_on_a_robot_keeps_the_contract(tmp_path):
    """Copied onto the robot without the package: a bad flag is one ``error:`` line, exit 2."""
    alone = tmp_path / "watchdog.py"
    alone.write_text((ROOT / "ssbl_pb" / "deploy" / "watchdog.py").read_text())
    # -S: no site-packages, so the package (installed editable) cannot be imported, as on the robot
    res = subprocess.run([sys.executable, "-S", str(alone), "--limit", "soon"], capture_output=True, text=True,
                         cwd=tmp_path, timeout=60)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: argument --limit"), res.stderr


def test_walker_faults_run_several_seeds_and_are_summed_up_with_their_entries():
    from ssbl_pb.bench.deploy import walker_summary

    runs = [{"fault": "member_steps_in", "seed": 500_000 + k, "exit_code": 0, "true_min_clearance_m": c,
             "walker_acted_at": 3.0 if k != 1 else None} for k, c in enumerate((0.52, 0.61, 0.44))]
    once = [{"fault": "stranger_steps_in", "seed": 11, "exit_code": 0, "true_min_clearance_m": 0.7}]
    lines = walker_summary(runs + once + [{"fault": "sigint", "exit_code": 130}])
    assert lines == ["`member_steps_in` over 3 runs (seeds 500000-500002; the walker acted in 2): intimate-zone "
                     "entries **1**, smallest true clearance 0.44 m.", ""]
