"""The calibration, Table I and sweep tools' inputs, run in this process: side outputs checked before
any work, tools that exit 2 say nothing else first, interrupted tools stop their workers, success intervals stay
within 0-100 %."""

from __future__ import annotations

import importlib.util
import multiprocessing as mp
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from ssbl_pb.cli import run

ROOT = Path(__file__).resolve().parents[1]


def tool(name: str) -> ModuleType:
    """``tools/NAME.py`` as a module (its ``main`` runs in this process)."""
    spec = importlib.util.spec_from_file_location(f"probe_tool_{name}", ROOT / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def exit_code(name: str, argv: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    """``tools/NAME.py argv`` under ``cli.run``: its exit code and every non-empty line it printed, Python's
    and C libraries' alike (stdout and stderr)."""
    main = tool(name).main
    capfd.readouterr()
    with pytest.raises(SystemExit) as exc:
        run(main, argv)
    out, err = capfd.readouterr()
    return int(exc.value.code), [ln for ln in (out + err).splitlines() if ln.strip()]


# -- side outputs (.png, .md) are output paths too: checked before any work -----------------------------------
def _groups(tmp: Path) -> list[str]:
    from test_groups import PAIR_AND_TRIO, write_dataset

    write_dataset(tmp / "data" / "a", [PAIR_AND_TRIO] * 3, [[[1, 2], [3, 4, 5]]] * 3)
    return [str(tmp / "data"), "--per-size", "5"]


def _map(tmp: Path) -> list[str]:
    from test_calib_map import write_map

    from ssbl_pb.calib.room_map import read_map

    path = write_map(tmp)
    seed = read_map(path).cell_to_map(np.array([[70, 30]]))[0]  # inside its room
    return [str(path), "--seed", *(f"{v:.3f}" for v in seed)]


def _dynamics(tmp: Path) -> list[str]:
    log = tmp / "log.csv"
    assert tool("identify_dynamics").main([str(log), "--simulate", "--dt", "0.05"]) == 0
    return [str(log)]


def _scan(tmp: Path) -> list[str]:
    import open3d as o3d

    from ssbl_pb.calib.pointcloud import synthetic_room

    pts = synthetic_room(size=(6.0, 4.0), height=1.15, pitch_deg=10.0, roll_deg=0.0, noise=0.005, n=20000, seed=1)
    path = tmp / "scan.pcd"
    o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)))
    return [str(path)]


def _camera(tmp: Path) -> list[str]:
    data = ROOT.parent / "shared" / "data" / "calib"
    if not data.is_dir():
        pytest.skip(f"real data folder {data} is absent")
    return [str(p) for p in sorted(data.glob("left0[1-6].jpg"))]


@pytest.mark.parametrize("name, inputs, side", [
    ("calibrate_groups", _groups, ".png"),
    ("calibrate_groups", _groups, ".md"),
    ("import_map", _map, ".png"),
    ("identify_dynamics", _dynamics, ".md"),
    ("fit_room_pointcloud", _scan, ".png"),
    ("calibrate_camera", _camera, ".md"),
])
def test_a_side_output_that_is_a_folder_is_refused_before_any_work(
        name: str, inputs: Callable[[Path], list[str]], side: str, tmp_path: Path,
        capfd: pytest.CaptureFixture[str]) -> None:
    argv = inputs(tmp_path)
    out = tmp_path / "res" / "out.yaml"
    out.with_suffix(side).mkdir(parents=True)  # e.g. OUT.png: an existing folder
    code, lines = exit_code(name, [*argv, "--out", str(out)], capfd)
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"error: --out {out}: its {side} file") and "is a directory" in lines[0], lines
    assert sorted(p.name for p in out.parent.iterdir()) == [out.with_suffix(side).name]  # nothing written


def test_a_side_output_named_as_the_main_output_is_refused(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "room.png"  # the room YAML would be overwritten by its own figure
    code, lines = exit_code("import_map", [*_map(tmp_path), "--out", str(out)], capfd)
    assert code == 2 and lines == [f"error: --out {out}: the .png file goes beside it with the same name; give "
                                   f"another suffix (e.g. .yaml)"]
    assert not out.exists()


# -- exit 2 says one line and nothing before it ---------------------------------------------------------------
def test_unreadable_point_clouds_print_no_open3d_warnings(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "text.pcd").write_text("garbage text\n")
    (tmp_path / "empty.ply").write_bytes(b"")
    for name, why in (("text.pcd", "0 finite points"), ("empty.ply", "RPly: Unable to read magic number")):
        code, lines = exit_code("fit_room_pointcloud", [str(tmp_path / name), "--out", str(tmp_path / "o.yaml")],
                                capfd)
        assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {tmp_path / name}: "), lines
        assert why in lines[0]
    assert not list(tmp_path.glob("o.*"))


def test_a_log_with_no_command_fails_before_any_progress_line(tmp_path: Path,
                                                              capfd: pytest.CaptureFixture[str]) -> None:
    rows = ["t,cmd_vx,cmd_vy,cmd_wz,odom_x,odom_y,odom_yaw"] + [f"{0.1 * i:.2f},0,0,0,0,0,0" for i in range(40)]
    (tmp_path / "still.csv").write_text("\n".join(rows) + "\n")
    code, lines = exit_code("identify_dynamics", [str(tmp_path / "still.csv")], capfd)
    assert (code, lines) == (2, [f"error: {tmp_path / 'still.csv'}: no axis is ever commanded"])


def test_non_monotonic_timestamps_are_printed_as_plain_numbers(tmp_path: Path,
                                                               capfd: pytest.CaptureFixture[str]) -> None:
    rows = ["t,cmd_vx,cmd_vy,cmd_wz,odom_x,odom_y,odom_yaw"] + [f"{0.1 * i:.2f},0.1,0,0,0,0,0" for i in range(30)]
    rows[12] = "0.50,0.1,0,0,0,0,0"
    (tmp_path / "back.csv").write_text("\n".join(rows) + "\n")
    code, lines = exit_code("identify_dynamics", [str(tmp_path / "back.csv")], capfd)
    assert code == 2 and lines[0].endswith("not strictly increasing at row 13 (t = 0.5 after 1.0)"), lines


def test_camera_stability_beyond_the_images_is_refused_before_reading_them(
        tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    images = [str(tmp_path / f"missing{i}.jpg") for i in range(4)]  # never read: the check comes first
    code, lines = exit_code("calibrate_camera", [*images, "--stability", "2", "--out", str(tmp_path / "c.yaml")],
                            capfd)
    assert code == 2 and lines == ["error: --stability 2: leaving 2 out of 4 images keeps fewer than 3; give more "
                                   "images or a smaller K"]


def test_camera_pose_names_the_camera_yaml_its_checks_refuse(tmp_path: Path,
                                                             capfd: pytest.CaptureFixture[str]) -> None:
    cam = tmp_path / "cam.yaml"
    cam.write_text("image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [-500, 0, 320, 0, "
                   "500, 240, 0, 0, 1]}\ndistortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
    code, lines = exit_code("camera_pose", [str(tmp_path / "floor.png"), "--camera", str(cam), "--square", "0.1",
                                            "--out", str(tmp_path / "posed.yaml")], capfd)
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {cam}: camera "), lines
    assert "fx=-500.0" in lines[0] and not (tmp_path / "posed.yaml").exists()


def test_a_yaml_path_that_is_a_folder_says_so(tmp_path: Path) -> None:
    from ssbl_pb.params import ConfigError, load_yaml

    with pytest.raises(ConfigError, match=f"^{tmp_path}: is a directory, expected a YAML file$"):
        load_yaml(tmp_path)
    (tmp_path / "bin.yaml").write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ConfigError, match="bin.yaml: not UTF-8 text, expected a YAML file"):
        load_yaml(tmp_path / "bin.yaml")


# -- interrupted: the workers go quietly, before what they read goes ----------------------------------------------
def _serve_slowly(seconds: float) -> None:
    time.sleep(seconds)


def test_ship_policy_stops_its_evaluation_workers_when_interrupted(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    import ssbl_pb.policies

    shutil.copytree(ROOT / "ssbl_pb" / "policies" / "vector", tmp_path / "run")
    monkeypatch.setattr(ssbl_pb.policies, "SHIPPED_DIR", tmp_path / "policies")
    (tmp_path / "policies").mkdir()
    ship = tool("ship_policy")
    workers: list[mp.process.BaseProcess] = []

    def evaluate(policy: str, seeds: range, label: str) -> dict:  # a pool started, then Ctrl-C
        workers.append(mp.get_context("spawn").Process(target=_serve_slowly, args=(60.0,), daemon=True))
        workers[-1].start()
        raise KeyboardInterrupt

    monkeypatch.setattr(ship, "evaluate", evaluate)
    with pytest.raises(KeyboardInterrupt):
        ship.main([str(tmp_path / "run"), "--model", "final", "--name", "probe", "--episodes", "1"])
    assert workers and not workers[0].is_alive()  # stopped before the stage it read was removed
    assert list((tmp_path / "policies").iterdir()) == []


# -- success intervals: Wilson, inside 0-100 % --------------------------------------------------------------------
def test_wilson_interval_by_hand_and_proportions_stay_in_range() -> None:
    from ssbl_pb.analysis.report import mean_ci, proportion_ci, wilson_interval

    # p = 0.5 over 10: centre 0.5, half 1.96 sqrt(0.025 + 0.0096) / 1.384 = 0.2634
    assert wilson_interval(0.5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson_interval(0.0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    ci = proportion_ci([1.0, 1.0, 0.0])  # 0/1 outcomes: Wilson over the 3 of them
    assert (ci["mean"], ci["ci_low"], ci["ci_high"]) == pytest.approx((2 / 3, 0.2077, 0.9385), abs=1e-4)
    seeds = [0.2, 1.0]  # the probe's sweep: two seeds far apart; Student t gives [-4.5, 5.7]
    assert mean_ci(seeds)["ci_low"] < 0
    ci = proportion_ci(seeds, per_value=3)
    assert ci["mean"] == pytest.approx(0.6) and 0 <= ci["ci_low"] < 0.05 and 0.95 < ci["ci_high"] <= 1
    agree = proportion_ci([0.6, 0.6, 0.6], per_value=100)  # seeds agree: the pooled 300 episodes
    assert (agree["ci_low"], agree["ci_high"]) == pytest.approx(wilson_interval(0.6, 300), abs=1e-12)


def test_sweep_summary_success_cells_stay_within_0_100(tmp_path: Path) -> None:
    from ssbl_pb.sweep import load_spec
    from ssbl_pb.sweep.summary import SHOWN, _fmt, rows

    spec = load_spec(ROOT / "tests" / "sweep_specs" / "tiny.yaml")
    trials = spec.trials()
    success = [1 / 3, 1.0, 0.0, 2 / 3]
    records = {t.name: {"result": {"success_rate": s, "collision_rate": 1 - s, "violation_rate": s,
                                   "mean_return": -s}} for t, s in zip(trials, success, strict=True)}
    for row in rows(spec, records):
        for metric, _, scale, decimals in SHOWN[:1] + SHOWN[2:4]:
            low, high = row[f"{metric}_ci_low"], row[f"{metric}_ci_high"]
            assert 0 <= low <= row[f"{metric}_mean"] <= high <= 1, (row["config"], metric, low, high)
            cell = _fmt(row, metric, scale, decimals)  # "mean [low, high]" in %
            assert all(0 <= float(v) <= 100 for v in re.findall(r"-?\d+\.\d+", cell)), cell
        assert row["mean_return_ci_low"] < row["mean_return_mean"]  # other metrics: Student t as before
    assert np.isfinite(rows(spec, records)[0]["success_rate_ci_low"])
