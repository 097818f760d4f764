"""Training runs a hostile tester cannot break: --overwrite removes only a run, best/ and the final
model are one unit each, a run is resumable from its first file, corrupt run files are one-line errors, and
evaluation workers die with their tool."""

from __future__ import annotations

import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
import types
import zipfile
from pathlib import Path

import pytest

from ssbl_pb.agents.trained import ModelError, resolve_model
from ssbl_pb.training.config import load_config, save_config
from ssbl_pb.training.run import RunError

ROOT = Path(__file__).resolve().parents[1]
TINY = {"n_envs": 2, "total_steps": 256, "eval_every": 128, "eval_episodes": 2, "baseline_episodes": 1,
        "checkpoint_every": 128, "ppo": {"n_steps": 64, "batch_size": 64, "n_epochs": 1, "net_arch": [16, 16]}}


def tiny_config():
    return load_config(ROOT / "configs" / "vector_ff.yaml", TINY)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A tiny run trained in this process (a few seconds): final model, best/, checkpoints."""
    from ssbl_pb.training.run import train

    run = tmp_path_factory.mktemp("trained") / "run"
    train(tiny_config(), run)
    return run


@pytest.fixture
def run_copy(finished_run: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(finished_run, tmp_path / "run"))


def exit_code(tool: str, argv: list[str], capsys) -> tuple[int, list[str]]:
    """Run ``tools/TOOL`` in this process under ``cli.run``: (exit code, non-empty stderr lines)."""
    import importlib.util

    from ssbl_pb.cli import run

    spec = importlib.util.spec_from_file_location(f"tool_{tool[:-3]}", ROOT / "tools" / tool)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        run(module.main, argv)
    return int(exc.value.code), [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]


def fake_model(path: Path, step: int) -> None:
    """A stand-in for an SB3 archive: only its ``data`` entry (the step count) is read before loading."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("data", json.dumps({"num_timesteps": step}))


def fake_norm(path: Path, step: int | None) -> None:
    path.write_bytes(pickle.dumps(types.SimpleNamespace(**({} if step is None else {"ssbl_step": step}))))


# -- 9b: --overwrite ------------------------------------------------------------------------------------------
def test_overwrite_refuses_a_folder_that_holds_no_run_and_deletes_nothing(tmp_path: Path) -> None:
    from ssbl_pb.training.run import check_new_run

    folder = tmp_path / "data"
    folder.mkdir()
    (folder / "notes.txt").write_text("precious")
    with pytest.raises(RunError, match=r"--out \S*data: holds files but no training run"):
        check_new_run(tiny_config(), folder, overwrite=True)
    (folder / "config.yaml").write_text("just: a file of mine\n")  # a config.yaml, but not a run's
    with pytest.raises(RunError, match="holds files but no training run"):
        check_new_run(tiny_config(), folder, overwrite=True)
    assert sorted(p.name for p in folder.iterdir()) == ["config.yaml", "notes.txt"]
    empty = tmp_path / "empty"
    empty.mkdir()
    check_new_run(tiny_config(), empty, overwrite=True)  # an empty folder is fine
    (empty / "checkpoints").mkdir()  # as is a run killed between its first checkpoint and its config.yaml
    for name in ("ckpt_000000000.zip", "ckpt_000000000_vecnormalize.pkl", "latest.json"):
        (empty / "checkpoints" / name).write_text("x")
    check_new_run(tiny_config(), empty, overwrite=True)


def test_overwrite_removes_what_a_run_wrote_and_nothing_else(tmp_path: Path) -> None:
    from ssbl_pb.training.run import RUN_ENTRIES, remove_run

    run = tmp_path / "run"
    (run / "best").mkdir(parents=True)
    (run / "checkpoints").mkdir()
    save_config(tiny_config(), run / "config.yaml")
    for name in ("model.zip", "summary.json", ".model.ab12cd34.zip", "notes.txt", ".hidden-of-mine"):
        (run / name).write_text("x")
    (run / "mine").mkdir()
    remove_run(run)
    assert sorted(p.name for p in run.iterdir()) == [".hidden-of-mine", "mine", "notes.txt"]
    assert "checkpoints" in RUN_ENTRIES and "best" in RUN_ENTRIES


# -- 10: best/ and the final model are one unit each ---------------------------------------------------------
class _Norm(types.SimpleNamespace):
    def save(self, path: str) -> None:
        Path(path).write_bytes(pickle.dumps(types.SimpleNamespace(**vars(self))))


class _Model:
    def __init__(self, step: int, fail: bool = False) -> None:
        self.num_timesteps, self.fail, self.env = step, fail, _Norm()

    def get_env(self) -> _Norm:
        return self.env

    def save(self, path: Path) -> None:
        if self.fail:
            raise OSError("disk full")
        fake_model(Path(path), self.num_timesteps)


def test_best_is_replaced_as_one_unit(tmp_path: Path) -> None:
    from ssbl_pb.training.callbacks import EvalCheckpointCallback
    from ssbl_pb.training.run import clean_temporaries

    run = tmp_path / "run"
    run.mkdir()
    save_config(tiny_config(), run / "config.yaml")
    cb = EvalCheckpointCallback(run, None, 10, 1, 0, 10, False)
    cb.model = _Model(20_000)
    cb.save(run / "best", {"step": 20_000, "score": 0.1})
    before = {p.name: p.read_bytes() for p in (run / "best").iterdir()}
    assert sorted(before) == ["config.yaml", "eval.json", "model.zip", "vecnormalize.pkl"]
    cb.model = _Model(40_000, fail=True)  # the next save dies half-way: the old set stays whole
    with pytest.raises(OSError):
        cb.save(run / "best", {"step": 40_000, "score": 0.2})
    assert {p.name: p.read_bytes() for p in (run / "best").iterdir()} == before
    assert sorted(p.name for p in run.iterdir()) == ["best", "config.yaml"]  # no stage left
    cb.model = _Model(40_000)
    cb.save(run / "best", {"step": 40_000, "score": 0.2})
    assert resolve_model(str(run / "best"))[0] == run / "best" / "model.zip"
    # killed between replace_dir's two renames: the old set aside, no best/; the next start puts it back
    os.replace(run / "best", run / ".best.old-x1y2")
    (run / ".best.new-z3").mkdir()
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / ".ckpt_000000128.ab12cd34.zip").write_text("half")
    clean_temporaries(run)
    assert sorted(p.name for p in run.iterdir()) == ["best", "checkpoints", "config.yaml"]
    assert json.loads((run / "best" / "eval.json").read_text())["step"] == 40_000
    assert not any((run / "checkpoints").iterdir())


def test_a_model_whose_parts_disagree_is_refused(tmp_path: Path) -> None:
    """The probe's two cases: best/model.zip from step 40,000 beside normalisation and eval.json from 20,000,
    and a best/ killed in its first save (no vecnormalize.pkl): both one line, nothing evaluated."""
    from ssbl_pb.analysis.evaluation import Setup, evaluate

    run = tmp_path / "run"
    best = run / "best"
    best.mkdir(parents=True)
    save_config(tiny_config(), run / "config.yaml")
    shutil.copy(run / "config.yaml", best / "config.yaml")
    fake_model(best / "model.zip", 40_000)
    fake_norm(best / "vecnormalize.pkl", 20_000)
    (best / "eval.json").write_text(json.dumps({"step": 20_000, "score": 0.6}))
    with pytest.raises(ModelError, match=r"best: its parts disagree \(model.zip from step 40000, vecnormalize.pkl "
                                         r"from step 20000, eval.json from step 20000\)"):
        evaluate(Setup(str(best)), 2, 0, tmp_path / "eval")
    fake_norm(best / "vecnormalize.pkl", None)  # saved before the stamp: eval.json still tells
    with pytest.raises(ModelError, match=r"eval.json from step 20000"):
        resolve_model(str(run))  # the run's best is what a run directory without model.zip gives
    (best / "vecnormalize.pkl").unlink()
    (best / "eval.json").unlink()
    with pytest.raises(ModelError, match="model.zip has no vecnormalize.pkl beside it"):
        resolve_model(str(best))
    assert not (tmp_path / "eval").exists()


def test_a_final_model_saved_half_way_is_refused_and_resume_finishes_it(run_copy: Path, capsys) -> None:
    from ssbl_pb.training.run import resume

    assert resolve_model(str(run_copy))[0] == run_copy / "model.zip"  # a real run passes the checks
    assert resolve_model(str(run_copy / "best"))[1] == run_copy / "best" / "vecnormalize.pkl"
    fake_norm(run_copy / "vecnormalize.pkl", 0)  # killed between the final files: normalisation of another step
    (run_copy / "summary.json").unlink()
    code, err = exit_code("evaluate.py", ["--policy", str(run_copy), "--episodes", "2", "--out",
                                          str(run_copy.parent / "eval")], capsys)
    assert code == 2 and len(err) == 1 and "parts disagree" in err[0] and f"--resume {run_copy}" in err[0], err
    for stale in (run_copy / ".model.ab12cd34.zip", run_copy / "best" / ".eval.zz99yy88.json"):
        stale.write_text("half")
    (run_copy / ".best.new-abc").mkdir()
    summary = resume(run_copy)
    assert summary["steps"] == 256 and resolve_model(str(run_copy))[1] == run_copy / "vecnormalize.pkl"
    assert not [p for p in run_copy.rglob(".*") if "tb" not in p.parts]  # stale temporaries cleaned


# -- 11: resumable from the first file ------------------------------------------------------------------------
def test_a_run_killed_while_setting_up_resumes(tmp_path: Path, monkeypatch) -> None:
    import ssbl_pb.training.run as R

    run = tmp_path / "run"
    run.mkdir()  # an existing folder: nothing removes what the kill left
    written = []
    real_save_config = R.save_config
    monkeypatch.setattr(R, "save_config", lambda cfg, path: (
        written.append((path.parent / "checkpoints" / "latest.json").is_file()), real_save_config(cfg, path)))

    def killed(cfg):
        raise KeyboardInterrupt  # as SIGKILL while the baselines run: config.yaml is there

    monkeypatch.setattr(R, "baseline_returns", killed)
    with pytest.raises(KeyboardInterrupt):
        R.train(tiny_config(), run)
    assert written == [True]  # checkpoint 0 existed before config.yaml made the folder a run
    assert not (run / "baselines.json").exists()
    monkeypatch.undo()
    summary = R.resume(run)
    assert summary["resumed_from"] == 0 and summary["steps"] == 256
    assert set(json.loads((run / "baselines.json").read_text())) == {"random", "sffm"}


def test_a_new_run_removes_the_temporaries_of_one_killed_before_its_config(tmp_path: Path, monkeypatch) -> None:
    """Killed while writing checkpoint 0 (before config.yaml): its 0-byte temporaries stay in checkpoints/; the
    same command again removes them (its own names only) and writes a real checkpoint 0."""
    import ssbl_pb.training.run as R

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for name in (".ckpt_000000000.ab12cd34.zip", ".ckpt_000000000_vecnormalize.x9y8z7w6.pkl"):
        (run / "checkpoints" / name).write_bytes(b"")
    (run / "checkpoints" / ".notes-of-mine").write_text("kept")

    def killed(cfg):
        raise KeyboardInterrupt

    monkeypatch.setattr(R, "baseline_returns", killed)  # stop once the checkpoint and config.yaml are written
    with pytest.raises(KeyboardInterrupt):
        R.train(tiny_config(), run)
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == [
        ".notes-of-mine", "ckpt_000000000.zip", "ckpt_000000000_vecnormalize.pkl", "latest.json"]
    assert R.latest_checkpoint(run)[0].stat().st_size > 1000


def test_sigkill_as_soon_as_the_run_appears_leaves_it_resumable(tmp_path: Path) -> None:
    from ssbl_pb.training.run import latest_checkpoint

    run = tmp_path / "run"
    args = [f"--set={k}={v}" for k, v in (("eval_episodes", 1), ("baseline_episodes", 5), ("ppo.n_steps", 64),
                                          ("ppo.batch_size", 64), ("ppo.net_arch", "[16,16]"))]
    proc = subprocess.Popen([sys.executable, str(ROOT / "tools" / "train_pb.py"), "--total-steps", "256",
                             "--n-envs", "2", "--out", str(run), *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not (run / "config.yaml").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert (run / "config.yaml").is_file()
    assert latest_checkpoint(run)[2] == 0  # --resume has a checkpoint to start from


# -- 13: corrupt run files are one line ----------------------------------------------------------------------
@pytest.mark.parametrize("index", ["[]", '{"step": "x", "model": 3}', '{"step": 0, "model": "../../etc.zip"}',
                                   "{not json", '{"model": "ckpt_000000000.zip"}'])
def test_a_bad_checkpoint_index_is_one_line(run_copy: Path, index: str, capsys) -> None:
    (run_copy / "checkpoints" / "latest.json").write_text(index)
    (run_copy / "summary.json").unlink()
    code, err = exit_code("train_pb.py", ["--resume", str(run_copy)], capsys)
    assert code == 2 and len(err) == 1 and "latest.json: unreadable checkpoint index" in err[0], err


def test_a_checkpoint_whose_normalisation_is_from_another_step_is_refused(run_copy: Path) -> None:
    from ssbl_pb.training.run import resume

    latest = json.loads((run_copy / "checkpoints" / "latest.json").read_text())
    norm = run_copy / "checkpoints" / latest["model"].replace(".zip", "_vecnormalize.pkl")
    shutil.copy(run_copy / "checkpoints" / "ckpt_000000000_vecnormalize.pkl", norm)
    (run_copy / "summary.json").unlink()
    with pytest.raises(RunError, match=r"holds 256 steps, its normalisation 0, its index says 256"):
        resume(run_copy)
    (run_copy / "checkpoints" / latest["model"]).write_bytes(b"not a zip")
    with pytest.raises(RunError, match="cannot load the checkpoint"):
        resume(run_copy)


def test_a_corrupt_run_config_is_one_line_naming_it(run_copy: Path, capsys) -> None:
    for text in ("a: [b\n", "- 1\n- 2\n"):
        (run_copy / "config.yaml").write_text(text)
        code, err = exit_code("evaluate.py", ["--policy", str(run_copy), "--episodes", "2", "--out",
                                              str(run_copy.parent / "eval")], capsys)
        assert code == 2 and len(err) == 1 and f"{run_copy / 'config.yaml'}:" in err[0], err
    assert not (run_copy.parent / "eval").exists()


def test_a_bug_while_fine_tuning_keeps_its_traceback(tmp_path: Path, monkeypatch) -> None:
    """Only reading the source run's files is bad input (exit 2); a failure after that is a bug (exit 1)."""
    import ssbl_pb.training.run as R

    cfg = load_config(None, {"n_envs": 1, "ppo": {"net_arch": [128, 128]}})
    venv = R.make_vec_env(cfg, 0)
    model = R.build_model(cfg, venv, tmp_path / "tb")
    monkeypatch.setattr(R, "_match_action_head", lambda *a: 1 // 0)
    with pytest.raises(ZeroDivisionError):
        R._init_from(model, venv, ROOT / "ssbl_pb" / "policies" / "vector")
    bad = Path(shutil.copytree(ROOT / "ssbl_pb" / "policies" / "vector", tmp_path / "bad"))
    (bad / "vecnormalize.pkl").write_bytes(b"not a pickle")
    with pytest.raises(RunError, match=r"--init-from \S*bad: cannot read its model"):
        R._init_from(model, venv, bad)
    venv.close()


# -- 15: evaluation workers die with their tool ---------------------------------------------------------------
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_episode_workers_die_with_their_sigkilled_tool(tmp_path: Path) -> None:
    """Every tool's episode pool (evaluate, compare, bench_policies, ship_policy: ``rollout.run_episodes``):
    SIGKILL the tool while its workers play, and no worker is left running."""
    script = tmp_path / "tool.py"
    script.write_text(
        "import os, sys\n"
        "from ssbl_pb.analysis.evaluation import Setup\n"
        "from ssbl_pb.agents.rollout import run_episodes\n"
        "if __name__ == '__main__':\n"
        "    print(os.getpid(), flush=True)\n"
        "    run_episodes(Setup('sffm'), range(100000), workers=2)\n")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    parent = int(proc.stdout.readline())
    deadline, workers = time.monotonic() + 60, []
    while time.monotonic() < deadline and len(workers) < 2:  # the pool's workers (and its resource tracker)
        time.sleep(0.2)
        workers = _children(parent)
    assert len(workers) >= 2, "the pool never started"
    time.sleep(2.0)  # they build their envs and play
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers), "a worker outlived its SIGKILLed tool"


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie waits only for its (new) parent to reap it
