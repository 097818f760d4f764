"""Table I (ssbl_pb/analysis/table1.py, table1_report.py, tools/table1.py): the paper's formulas by hand,
aggregation over seeds, rows as sweep trials resumed one by one, and a smoke run of the tool."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from ssbl_pb.analysis.table1 import BUDGETS, ROWS, find_row, percent, row_config, row_trials, smoothed_best
from ssbl_pb.analysis.table1_report import aggregate, ordering_checks, ordering_detail


def test_smoothed_best_and_percentage_by_hand() -> None:
    # s: 0, 0.5 * 0 + 0.5 * 4 = 2, 0.5 * 2 + 0.5 * (-2) = 0, 0.5 * 0 + 0.5 * 3 = 1.5 -> best 2
    assert smoothed_best([0.0, 4.0, -2.0, 3.0], 0.5) == pytest.approx(2.0)
    assert smoothed_best([-3.0], 0.9) == -3.0
    # the paper's numbers: CameraSpeed + SAEV + LSTM -0.544 between random -1.684 and Vector -0.256 -> 79.8 %
    assert percent(-0.544, -1.684, -0.256) == pytest.approx(79.83, abs=0.01)
    assert find_row("cameraspeed_saev_lstm").label == "CameraSpeed + SAEV + LSTM"
    assert len({r.slug for r in ROWS}) == len(ROWS) == 10


def _res(row: str, seed: int, reward: float, success: float = 0.5) -> dict:
    return {"row": row, "seed": seed, "reward": reward, "success_rate": success, "steps": 1, "seconds": 1.0}


def test_aggregate_takes_percentages_per_seed() -> None:
    results = [_res("Vector + LSTM", 0, 10.0, 1.0), _res("Random policy", 0, 0.0, 0.0),
               _res("CameraSpeed + SAEV + LSTM", 0, 8.0), _res("Vector + LSTM", 1, 20.0, 1.0),
               _res("Random policy", 1, 10.0, 0.0), _res("CameraSpeed + SAEV + LSTM", 1, 19.0)]
    rows = {r["row"]: r for r in aggregate(results)}
    cs = rows["CameraSpeed + SAEV + LSTM"]
    assert cs["percent"] == pytest.approx(85.0)  # seed 0: 80 %, seed 1: 90 %
    assert cs["percent_sd"] == pytest.approx(7.0711, abs=1e-3)
    assert cs["reward"] == pytest.approx(13.5) and cs["seeds"] == [0, 1] and cs["paper_percent"] == 79.80
    assert list(rows) == ["Vector + LSTM", "CameraSpeed + SAEV + LSTM", "Random policy"]  # the paper's order
    checks = dict(ordering_checks(list(rows.values())))
    assert checks["Vector + LSTM > CameraSpeed + SAEV + LSTM"] is True
    assert checks["CameraSpeed + SAEV + LSTM >= 80 %"] is True
    assert checks["CameraOnly + SAEV + FF > Random policy"] is None  # row missing
    assert math.isnan(cs["test_percent"])  # no held-out returns given
    assert rows["Vector + LSTM"]["success_percent_by_seed"] == [100.0, 100.0] and cs["success_percent"] == 50.0


def test_held_out_return_gets_its_own_percentages_and_ordering() -> None:
    # table reward: conv ahead (best evaluation); held-out return: SAEV ahead
    results = []
    for seed in (0, 1):
        for row, rew, ret in (("Vector + LSTM", 10.0, 8.0), ("Random policy", 0.0, 0.0),
                              ("CameraOnly + SAEV + LSTM", 6.0, 6.0 + seed), ("CameraOnly + conv + LSTM", 7.0, 5.0)):
            results.append(_res(row, seed, rew) | {"mean_return": ret})
    rows = aggregate(results)
    saev = next(r for r in rows if r["row"] == "CameraOnly + SAEV + LSTM")
    assert saev["test_percent_by_seed"] == pytest.approx([75.0, 87.5])  # 6 / 8, 7 / 8
    assert saev["test_return"] == pytest.approx(6.5) and saev["percent"] == pytest.approx(60.0)
    statement = "CameraOnly + SAEV + LSTM >= CameraOnly + conv + LSTM"
    assert dict(ordering_checks(rows))[statement] is False
    assert dict(ordering_checks(rows, "test_percent"))[statement] is True
    assert math.isnan(saev["test_jerk_cost"])  # trials that did not record it
    # held-out success (all 0.5 here): >= holds in both seeds, > (against random) in none
    success = {d["statement"]: d for d in ordering_detail(rows, "success_percent")}
    assert success[statement]["holds"] is True and success[statement]["seeds_holding"] == 2
    assert success["CameraOnly + SAEV + LSTM > Random policy"]["holds"] is False
    assert "CameraSpeed + SAEV + LSTM >= 80 %" not in success  # the target is on the reward's scale


def test_jerk_cost_is_averaged_and_shown(tmp_path: Path) -> None:
    from ssbl_pb.analysis.table1_report import write_rows, write_table

    results = [_res("Vector + LSTM", s, 10.0, 1.0) | {"jerk_cost": 1.0 + s} for s in (0, 1)]
    results += [_res("Random policy", s, 0.0, 0.0) | {"jerk_cost": 30.0} for s in (0, 1)]
    results += [_res("CameraOnly + SAEV + FF", 0, 5.0)]  # an older trial: no jerk cost recorded
    rows = {r["row"]: r for r in write_table(tmp_path, results, BUDGETS["smoke"], "cmd")}
    assert rows["Vector + LSTM"]["test_jerk_cost"] == pytest.approx(1.5)
    assert rows["Vector + LSTM"]["test_jerk_cost_sd"] == pytest.approx(0.7071, abs=1e-4)
    md = (tmp_path / "table1.md").read_text()
    assert "| held-out percent | jerk cost | success |" in md
    assert "| 1.50 ± 0.71 | 100 % | 2 |" in md and "| 30.00 | 0 % | 2 |" in md
    assert "| CameraOnly + SAEV + FF | 5.000 | 50.0 % | - | - | - | 50 % | 1 |" in md
    # a committed table1.json of before success_percent: its statements on success still come out
    old = [{k: v for k, v in r.items() if not k.startswith("success_percent")} for r in rows.values()]
    write_rows(tmp_path, old, BUDGETS["smoke"], "cmd")
    assert "- Vector + LSTM > CameraSpeed + SAEV + LSTM: row missing" in (tmp_path / "table1.md").read_text()
    assert "- CameraOnly + SAEV + FF > Random policy: holds\n" in (tmp_path / "table1.md").read_text()


def test_ordering_pairs_seeds_and_tests_them_by_hand() -> None:
    # random 0 and Vector + LSTM 10 per seed: a row's percentage is 10 x its reward
    results = []
    for seed, saev in enumerate((9.1, 9.2, 8.7)):
        results += [_res("Vector + LSTM", seed, 10.0), _res("Random policy", seed, 0.0),
                    _res("CameraOnly + SAEV + FF", seed, saev), _res("CameraOnly + conv + FF", seed, 9.0)]
    detail = {d["statement"]: d for d in ordering_detail(aggregate(results))}
    d = detail["CameraOnly + SAEV + FF >= CameraOnly + conv + FF"]
    # differences 1, 2, -3 points: mean 0, so the t statistic is 0 and p is 1; the mean 90 >= 90 holds
    assert d["holds"] is True and d["mean_diff"] == pytest.approx(0.0, abs=1e-9)
    assert (d["seeds_holding"], d["seeds_paired"]) == (2, 3) and d["p_paired"] == pytest.approx(1.0)
    results[-2] = _res("CameraOnly + SAEV + FF", 2, 9.3)  # differences 1, 2, 3: t = 2 / (1 / sqrt 3) = 3.464,
    d = {x["statement"]: x for x in ordering_detail(aggregate(results))}[
        "CameraOnly + SAEV + FF >= CameraOnly + conv + FF"]
    # two-sided p with 2 degrees of freedom: 1 - t / sqrt(t^2 + 2) = 1 - 3.464 / 3.742 = 0.0742
    assert d["mean_diff"] == pytest.approx(2.0) and d["p_paired"] == pytest.approx(0.0742, abs=1e-4)
    assert detail["CameraSpeed + SAEV + LSTM > CameraOnly + SAEV + FF"]["holds"] is None  # row missing
    # the paper's own Table I: SAEV 57.06 % < conv 61.18 % (CameraOnly + FF), SAEV 61.63 % >= conv 41.51 % (LSTM)
    assert d["paper_holds"] is False
    assert detail["CameraOnly + SAEV + LSTM >= CameraOnly + conv + LSTM"]["paper_holds"] is True
    assert detail["CameraSpeed + SAEV + LSTM >= 80 %"]["paper_holds"] is False  # 79.80 %


def test_rows_are_sweep_trials_and_a_finished_one_is_read_back(tmp_path: Path) -> None:
    from ssbl_pb.sweep import run_trials
    from ssbl_pb.sweep.runner import RESULT, _normal, trial_dir

    rows = [find_row("vector_ff"), find_row("cameraonly_saev_ff")]
    trials = row_trials(rows, 2, BUDGETS["full"], {"saev": "/x/saev.pt", "conv": "/x/conv.pt"})
    assert [t.name for t in trials] == ["vector_ff,seed=0", "cameraonly_saev_ff,seed=0", "vector_ff,seed=1",
                                        "cameraonly_saev_ff,seed=1"]
    assert trials[0].definition()["encoder"] is None and trials[1].definition()["encoder"] == "/x/saev.pt"
    # frozen-encoder features reach the policy raw, the vector standardised; a table run otherwise is stale
    assert [t.definition()["normalize_obs"] for t in trials[:2]] == [True, False]
    assert all("feature_smoothing" not in t.definition() for t in trials)  # off: the definitions run before
    low = row_trials(rows, 1, BUDGETS["full"], {"saev": "/x/saev.pt"}, feature_smoothing=0.5)
    assert "feature_smoothing" not in low[0].definition()  # the vector row has no features to filter
    assert low[1].definition()["feature_smoothing"] == 0.5  # a table with the low-pass is another table
    from ssbl_pb.perception.autoencoding import autoencoders as A
    from ssbl_pb.perception.autoencoding.ae_train import save_checkpoint

    saev_ckpt = save_checkpoint(tmp_path / "saev.pt", A.build("saev", A.SIZES["cpu"]).eval())
    cfgs = [row_config(r, 0, BUDGETS["full"], {"saev": str(saev_ckpt)}, 0.5) for r in rows]
    assert "feature_smoothing" not in cfgs[0] and cfgs[1]["feature_smoothing"] == 0.5
    done = _res("Vector + FF", 1, -5.0)
    path = trial_dir(tmp_path, trials[2].name) / RESULT
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"task": _normal(trials[2].definition()), "result": done}))
    outcome = run_trials(trials[2:3], tmp_path, workers=1)
    assert outcome.records[trials[2].name]["result"] == done and not outcome.failed
    assert sorted(p.name for p in path.parent.iterdir()) == [RESULT]  # read back: nothing trained


@pytest.mark.slow
def test_smoke_table_and_resume(tmp_path: Path) -> None:
    from tests.test_contracts import run_tool

    out = tmp_path / "t1"
    argv = ["--budget", "smoke", "--seeds", "1", "--out", str(out),
            "--rows", "vector_lstm,random_policy,cameraspeed_saev_lstm,cameraonly_conv_ff"]
    res = run_tool("table1.py", argv, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = json.loads((out / "table1.json").read_text())
    assert [r["row"] for r in rows] == ["Vector + LSTM", "CameraOnly + conv + FF", "CameraSpeed + SAEV + LSTM",
                                        "Random policy"]
    for r in rows:
        assert set(r) >= {"row", "reward", "percent", "success_rate", "seeds"} and r["seeds"] == [0]
        assert r["test_jerk_cost"] > 0  # every policy here changes its speed: the jerk cost takes some return
    assert rows[0]["percent"] == pytest.approx(100.0) and rows[-1]["percent"] == pytest.approx(0.0)
    md = (out / "table1.md").read_text()
    assert "| CameraSpeed + SAEV + LSTM |" in md and "79.80 %" in md
    assert (out / "ae" / "saev" / "keypoints.png").is_file() and (out / "ae" / "conv" / "encoder.pt").is_file()
    from ssbl_pb.env.gymenv.encoded import encoder_hfov  # the table's camera by default: the paper's 26.5 deg

    assert encoder_hfov(out / "ae" / "saev" / "encoder.pt") == encoder_hfov(out / "ae" / "conv" / "encoder.pt") == 26.5
    results = sorted((out / "trials").glob("*/result.json"))
    assert [p.parent.name for p in results] == ["cameraonly_conv_ff,seed=0", "cameraspeed_saev_lstm,seed=0",
                                                "random_policy,seed=0", "vector_lstm,seed=0"]
    tasks = {p.parent.name: json.loads(p.read_text())["task"] for p in results}  # the table's low-pass by default
    assert tasks["cameraspeed_saev_lstm,seed=0"]["feature_smoothing"] == 0.3
    assert tasks["cameraonly_conv_ff,seed=0"]["feature_smoothing"] == 0.3 and "feature_smoothing" not in tasks[
        "vector_lstm,seed=0"]
    stamps = {p: p.stat().st_mtime_ns for p in results}
    again = run_tool("table1.py", argv, timeout=120)  # every row finished: read back, nothing retrained
    assert again.returncode == 0, again.stderr[-2000:]
    assert {p: p.stat().st_mtime_ns for p in results} == stamps


def test_encoders_must_have_learned_through_the_tables_camera(tmp_path: Path) -> None:
    import torch

    from ssbl_pb.analysis.table1 import prepare_encoders
    from ssbl_pb.errors import UserError
    from ssbl_pb.perception.autoencoding import autoencoders as A
    from ssbl_pb.perception.autoencoding.ae_train import save_checkpoint

    torch.manual_seed(0)
    tiny = A.AESize("tiny", 24, (4, 6, 5), (3, 3, 3), 2, 12, (4, 4), 8, 6)
    narrow = str(save_checkpoint(tmp_path / "narrow.pt", A.build("saev", tiny).eval(),
                                 {"summary": {"camera_hfov_deg": 26.5}}))
    full = BUDGETS["full"]
    assert prepare_encoders(full, tmp_path, {"saev"}, {"saev": narrow}, camera_hfov_deg=26.5) == {"saev": narrow}
    assert prepare_encoders(full, tmp_path, {"saev"}, {"saev": narrow}) == {"saev": narrow}  # unset: its own
    with pytest.raises(UserError, match=r"saev encoder \S*narrow.pt: learned through a 26.5 deg camera, the table "
                                        r"asks for --camera-hfov 56.3"):
        prepare_encoders(full, tmp_path, {"saev"}, {"saev": narrow}, camera_hfov_deg=56.3)
    with pytest.raises(UserError, match=r"--conv \S*nosuch.pt: file not found"):
        prepare_encoders(full, tmp_path, {"conv"}, {"conv": str(tmp_path / "nosuch.pt")})
    assert not (tmp_path / "frames.npz").exists()  # nothing trained or collected


def _store(root: Path, trial, task: dict, finished: str = "2030-01-01T00:00:00") -> Path:
    from ssbl_pb.sweep.runner import RESULT, _normal, trial_dir

    path = trial_dir(root, trial.name) / RESULT
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"task": _normal(task), "result": _res(trial.row.label, trial.seed, -1.0),
                                "finished": finished}))
    return path


def _saev(path: Path, seed: int) -> Path:
    import torch

    from ssbl_pb.perception.autoencoding import autoencoders as A
    from ssbl_pb.perception.autoencoding.ae_train import save_checkpoint

    torch.manual_seed(seed)
    tiny = A.AESize("tiny", 24, (4, 6, 5), (3, 3, 3), 2, 12, (4, 4), 8, 6)
    return save_checkpoint(path, A.build("saev", tiny).eval(), {"summary": {"camera_hfov_deg": 26.5}})


def test_a_changed_reward_or_encoder_file_is_another_trial(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import hashlib

    from ssbl_pb.analysis import table1
    from ssbl_pb.errors import UserError
    from ssbl_pb.sweep import finished

    ckpt = _saev(tmp_path / "saev.pt", 0)
    rows = [find_row("vector_ff"), find_row("cameraonly_saev_ff")]
    trials = row_trials(rows, 1, BUDGETS["smoke"], {"saev": str(ckpt)})
    vector, camera = (t.definition() for t in trials)
    assert vector["reward"] == camera["reward"] == table1.table_reward()
    assert table1.table_reward()["reward_ramp"] == table1._default_reward()["reward_ramp"]  # configs/vector_ff.yaml
    assert camera["encoder_sha256"] == hashlib.sha256(ckpt.read_bytes()).hexdigest()
    assert "encoder_sha256" not in vector
    root = tmp_path / "table"
    for t in trials:
        _store(root, t, t.definition())
    assert sorted(finished(root, trials)) == sorted(t.name for t in trials)
    # configs/vector_ff.yaml edited: its reward is in every row's definition, so stored rows are not reused
    monkeypatch.setattr(table1, "_default_reward", lambda: {"reward": {"w_smooth": 0.1}})
    with pytest.raises(UserError, match=r"trial vector_ff,seed=0 was run with another definition \(reward changed"):
        finished(root, row_trials(rows[:1], 1, BUDGETS["smoke"], {}))
    monkeypatch.undo()
    _saev(ckpt, 1)  # the same path, other weights
    with pytest.raises(UserError, match=r"cameraonly_saev_ff,seed=0 was run with another definition "
                                        r"\(encoder_sha256 changed"):
        finished(root, row_trials(rows[1:], 1, BUDGETS["smoke"], {"saev": str(ckpt)}))


def test_rows_stored_before_reward_and_hash_were_recorded_are_kept_if_their_run_agrees(tmp_path: Path) -> None:
    import os

    import yaml

    from ssbl_pb.analysis.table1 import table_reward
    from ssbl_pb.errors import UserError
    from ssbl_pb.sweep import finished
    from ssbl_pb.sweep.runner import trial_dir

    ckpt = _saev(tmp_path / "saev.pt", 0)
    rows = [find_row("vector_ff"), find_row("cameraonly_saev_ff")]
    trials = row_trials(rows, 1, BUDGETS["smoke"], {"saev": str(ckpt)})
    root = tmp_path / "table"
    for t in trials:  # as written before this change: no reward, no hash
        old = {k: v for k, v in t.definition().items() if k not in ("reward", "encoder_sha256")}
        _store(root, t, old)
        (trial_dir(root, t.name) / "config.yaml").write_text(yaml.safe_dump({"name": t.name, **table_reward()}))
    assert sorted(finished(root, trials)) == sorted(t.name for t in trials)  # their runs trained this reward
    os.utime(ckpt, (time.time(), time.mktime((2031, 1, 1, 0, 0, 0, 0, 0, -1))))  # modified after they finished
    with pytest.raises(UserError, match="encoder_sha256 changed"):
        finished(root, trials[1:])
    (trial_dir(root, trials[0].name) / "config.yaml").write_text(
        yaml.safe_dump({**table_reward(), "reward_ramp": {}}))  # a run that trained another reward
    with pytest.raises(UserError, match="reward changed"):
        finished(root, trials[:1])
