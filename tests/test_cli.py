"""The shared contract pieces every tool uses: exit codes, one-line errors, progress in logs, safe outputs."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.cli import ArgumentParser, DeferredSignals, PlainBar, command_line, int_in, run
from ssbl_pb.errors import Terminated, UserError
from ssbl_pb.files import atomic_write, check_output_path, output_dir, write_text


def _exit_code(main) -> int:
    with pytest.raises(SystemExit) as exc:
        run(main, [])
    return int(exc.value.code)


def test_run_maps_user_errors_and_signals_to_exit_codes(capsys):
    def bad(argv):
        raise UserError("--thing 3: expected\n   something")

    assert _exit_code(bad) == 2
    assert capsys.readouterr().err == "error: --thing 3: expected something\n"  # one line
    assert _exit_code(lambda argv: (_ for _ in ()).throw(KeyboardInterrupt())) == 130
    assert _exit_code(lambda argv: (_ for _ in ()).throw(Terminated())) == 143
    assert _exit_code(lambda argv: 0) == 0
    with pytest.raises(ZeroDivisionError):  # a bug is not bad input: it keeps its traceback
        run(lambda argv: 1 // 0, [])
    with pytest.raises(ValueError):  # nor is a plain ValueError raised by numpy & co.
        run(lambda argv: int("x"), [])


def test_argument_errors_are_one_line_naming_the_flag():
    ap = ArgumentParser()
    ap.add_argument("--width", type=int_in(64, 4096))
    with pytest.raises(UserError, match=r"argument --width: 0: expected an integer in \[64, 4096\]"):
        ap.parse_args(["--width", "0"])
    with pytest.raises(UserError, match=r"argument --width: 'abc': expected an integer"):
        ap.parse_args(["--width", "abc"])
    assert ap.parse_args(["--width", "480"]).width == 480


def test_plain_progress_prints_a_few_lines_without_carriage_returns(capsys):
    bar = PlainBar(1000, "train", "step")
    for _ in range(1000):
        bar.update(1)
    bar.set_postfix_str("success 50%")
    bar.close()
    err = capsys.readouterr().err
    assert "\r" not in err and len(err.splitlines()) == 10  # one line per 10 %
    assert err.splitlines()[-1].startswith("train: 100 % (1000/1000 step")


def test_deferred_signals_wait_for_a_safe_point_then_raise():
    with DeferredSignals() as sig:
        os.kill(os.getpid(), signal.SIGTERM)
        assert sig.signum == signal.SIGTERM  # recorded, nothing raised yet
        with pytest.raises(Terminated):
            sig.raise_if_signalled()
    with DeferredSignals() as sig:
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):  # a second signal stops at once
            os.kill(os.getpid(), signal.SIGINT)


def test_command_line_records_the_arguments_as_typed_and_quoted(monkeypatch):
    argv = ["runs/my run", "--name", "camera_speed_saev", "--seed", "600000"]
    assert command_line("tools/ship_policy.py", argv) == ("python tools/ship_policy.py 'runs/my run' --name "
                                                          "camera_speed_saev --seed 600000")
    monkeypatch.setattr(sys, "argv", ["tools/x.py", "--force"])
    assert command_line("tools/x.py") == "python tools/x.py --force"


def test_output_dir_removes_only_what_it_created(tmp_path):
    keep = tmp_path / "existing"
    keep.mkdir()
    with pytest.raises(RuntimeError), output_dir(keep / "a" / "b") as out:
        write_text(out / "x.txt", "partial")
        raise RuntimeError("tool failed")
    assert keep.is_dir() and not (keep / "a").exists()
    with output_dir(keep / "c") as out:
        write_text(out / "x.txt", "done")
    assert (keep / "c" / "x.txt").read_text() == "done"


def test_check_output_path_refuses_paths_under_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(UserError, match="is a file, not a directory"):
        check_output_path(f / "sub" / "out")
    with pytest.raises(UserError, match="exists and is not a directory"):
        check_output_path(f)
    with pytest.raises(UserError, match="cannot create its folder"):
        write_text(f / "y.txt", "z")
    assert check_output_path(tmp_path / "new" / "dir") == tmp_path / "new" / "dir"
    assert not (tmp_path / "new").exists()  # checking creates nothing


def test_atomic_writes_keep_the_old_file_on_failure_and_use_normal_permissions(tmp_path):
    path = tmp_path / "result.json"
    write_text(path, "old")
    with pytest.raises(RuntimeError):
        atomic_write(path, lambda p: (p.write_text("half"), (_ for _ in ()).throw(RuntimeError()))[0])
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["result.json"]
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask  # not mkstemp's 0600


def test_config_messages_show_plain_numbers_and_name_their_file(tmp_path):
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.params import ConfigError, RobotParams

    with pytest.raises(ConfigError, match=r"robot.max_speed = -0.3: expected") as exc:
        RobotParams(max_speed=np.float64(-0.3))
    assert "np.float64" not in str(exc.value)
    bad = tmp_path / "robot.yaml"
    bad.write_text("max_speed: -1\n")
    with pytest.raises(ConfigError, match=f"{bad}: robot.max_speed = -1"):
        make_env(robot_yaml=str(bad))


def test_no_pybullet_banner_on_stderr(tmp_path):
    code = "import ssbl_pb.env.gymenv.approach as a; a.make_env().close()"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "pybullet build time" not in res.stderr + res.stdout


def _sleeping_tool(folder: Path, seconds: float) -> Path:
    """A tool under ``cli.run`` that says ``ready`` and sleeps ``seconds``."""
    script = folder / "tool.py"
    script.write_text(textwrap.dedent(f"""
        import time
        from ssbl_pb.cli import run
        def main(argv):
            print("ready", flush=True)
            time.sleep({seconds})
            return 0
        run(main)
    """))
    return script


def test_sigterm_in_a_tool_exits_143(tmp_path):
    script = _sleeping_tool(tmp_path, 30)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and err.strip() == "terminated (SIGTERM)"


def test_sighup_in_a_tool_exits_143_unless_started_under_nohup(tmp_path):
    """SIGHUP (the terminal or the ssh connection closed) ends a tool as SIGTERM does, through its clean-up;
    a tool started with SIGHUP ignored (nohup) keeps it ignored."""
    script = _sleeping_tool(tmp_path, 30)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_DFL))  # (pytest under nohup)
    assert proc.stdout.readline().strip() == "ready"
    proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and err.strip() == "terminated (SIGHUP)"
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))  # as nohup starts it
    assert proc.stdout.readline().strip() == "ready"
    proc.send_signal(signal.SIGHUP)
    with pytest.raises(subprocess.TimeoutExpired):
        proc.wait(1.0)  # still running
    proc.terminate()
    assert proc.wait(30) == 143


def test_tools_do_not_edit_sys_path():
    tools = Path(__file__).resolve().parents[1] / "tools"
    offenders = [p.name for p in tools.glob("*.py") if "sys.path" in p.read_text()]
    assert offenders == []


def test_a_tool_started_with_sigint_ignored_still_stops_on_ctrl_c(tmp_path):
    """A shell starts background jobs with SIGINT ignored; ``run`` restores Ctrl-C (exit 130), in-process and in
    a real background start."""
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        assert _exit_code(lambda argv: 0 if signal.getsignal(signal.SIGINT) is signal.default_int_handler else 1) == 0
    finally:
        signal.signal(signal.SIGINT, old)
    script = _sleeping_tool(tmp_path, 5)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert proc.stdout.readline().strip() == "ready"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and err.strip() == "interrupted (Ctrl-C)"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
def test_an_output_path_that_cannot_be_created_is_bad_input_even_for_root(tmp_path):
    with pytest.raises(UserError, match=r"--out /proc/x: "):  # os.access says yes to root there
        check_output_path("/proc/x")
    with pytest.raises(UserError, match=r"--log-dir /proc/x/y: "):
        with output_dir("/proc/x/y", "--log-dir"):
            pass
    assert check_output_path(tmp_path / "new") and [p.name for p in tmp_path.iterdir()] == []  # the probe is gone


def test_files_that_belong_together_are_renamed_together(tmp_path):
    from ssbl_pb.files import atomic_write_all, remove_temporaries, replace_dir

    a, b = tmp_path / "model.zip", tmp_path / "norm.pkl"
    atomic_write_all({a: lambda p: p.write_text("a1"), b: lambda p: p.write_text("b1")})

    def broken(p):
        raise OSError("disk full")

    with pytest.raises(OSError):  # the second file fails: neither is replaced, no temporary is left
        atomic_write_all({a: lambda p: p.write_text("a2"), b: broken})
    assert (a.read_text(), b.read_text()) == ("a1", "b1") and sorted(p.name for p in tmp_path.iterdir()) == [
        "model.zip", "norm.pkl"]
    stage, target = tmp_path / "stage", tmp_path / "best"
    for text in ("old", "new"):
        stage.mkdir()
        (stage / "x.txt").write_text(text)
        replace_dir(stage, target)
    assert (target / "x.txt").read_text() == "new" and not stage.exists()
    (tmp_path / ".model.ab12cd34.zip").write_text("half")  # a killed writer's temporaries, and one of another's
    (tmp_path / ".notes.ab12cd34.txt").write_text("not ours")
    (tmp_path / ".best.new-q1").mkdir()
    removed = remove_temporaries(tmp_path, lambda name: name == "model.zip", folders=("best",))
    assert sorted(p.name for p in removed) == [".best.new-q1", ".model.ab12cd34.zip"]
    assert (tmp_path / ".notes.ab12cd34.txt").exists()
