"""Base dynamics identification: known parameters recovered from noisy simulated logs; bad logs rejected."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.calib.dynamics import identify, simulate_axis
from ssbl_pb.calib.dynamics_log import excitation_plan, read_log, simulate_log, write_log
from ssbl_pb.params import CalibrationError, RobotParams, from_dict

ROOT = Path(__file__).resolve().parents[1]
FIELDS = ("latency_s", "time_constant_s", "max_accel", "max_speed", "max_yaw_rate", "max_yaw_accel")


def test_axis_model_equals_holonomic_base():
    true = RobotParams(latency_s=0.1, time_constant_s=0.3, max_accel=0.35, max_speed=0.3)
    cmd = excitation_plan(true, 0.02, seed=3, steps_per_axis=3)[:400]
    t, pose = simulate_log(true, cmd, 0.02, sim_dt=0.02)
    log_vel = np.gradient(pose[:, 0], t)  # vx only is excited in the first 400 rows
    model = simulate_axis(t, cmd[:, 0], np.array([0.1, 0.3, 0.35, 0.3]), window_mean=True, max_dt=0.02)
    assert np.abs(model[1:-1] - log_vel[1:-1]).max() < 1e-9


@pytest.mark.parametrize("true, dt, seed", [
    (RobotParams(latency_s=0.12, time_constant_s=0.25, max_accel=0.4, max_speed=0.3, max_yaw_rate=0.8,
                 max_yaw_accel=1.2), 0.02, 0),
    (RobotParams(latency_s=0.2, time_constant_s=0.15, max_accel=0.3, max_speed=0.35, max_yaw_rate=1.0,
                 max_yaw_accel=0.75), 0.05, 1),
])
def test_recovers_known_parameters_within_10_percent(tmp_path, true, dt, seed):
    cmd = excitation_plan(true, dt, seed=seed, steps_per_axis=5, hold_s=2.0)
    t, pose = simulate_log(true, cmd, dt, pose_noise=0.001, yaw_noise=0.002, seed=seed + 10)
    log = read_log(write_log(tmp_path / "log.csv", t, cmd, pose))
    res = identify(log)
    assert not res.notes
    for f in FIELDS:
        assert res.params[f] == pytest.approx(getattr(true, f), rel=0.10), f
    fitted = from_dict(RobotParams, res.params)  # the env loads the YAML this way
    _, pose = simulate_log(fitted, cmd, dt)
    assert np.abs(pose[:, :2] - simulate_log(true, cmd, dt)[1][:, :2]).max() < 0.05  # same path within 5 cm


def test_velocity_form_of_the_log(tmp_path):
    true = RobotParams(latency_s=0.1, time_constant_s=0.2, max_accel=0.5, max_speed=0.3)
    dt = 0.05
    cmd = excitation_plan(true, dt, seed=2, steps_per_axis=4)[:, :1]
    cmd = np.concatenate([cmd, np.zeros((len(cmd), 2))], axis=1)
    t, pose = simulate_log(true, cmd, dt)
    vel = np.gradient(pose[:, 0], t)  # instantaneous-ish; the fit treats the column as sampled velocity
    path = tmp_path / "vel.csv"
    rows = ["t,cmd_vx,cmd_vy,cmd_wz,odom_vx,odom_vy,odom_wz"]
    rows += [f"{a:.3f},{c[0]:.5f},0,0,{v:.6f},0,0" for a, c, v in zip(t, cmd, vel, strict=True)]
    path.write_text("\n".join(rows) + "\n")
    log = read_log(path)
    assert not log.from_pose
    res = identify(log)
    assert res.params["max_speed"] == pytest.approx(0.3, rel=0.05)
    assert "max_yaw_rate not" not in " ".join(res.notes)  # wz is never commanded: it is skipped, not fitted
    assert any("axis wz never commanded" in n for n in res.notes)


@pytest.mark.parametrize("text, match", [
    ("t,cmd_vx,cmd_vy,odom_x,odom_y,odom_yaw\n", r"missing column\(s\) \['cmd_wz'\]"),
    ("t,cmd_vx,cmd_vy,cmd_wz,odom_x\n", r"missing column\(s\) \['odom_x/odom_y/odom_yaw or odom_vx"),
])
def test_missing_columns(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text + "0,0,0,0,0,0\n" * 30)
    with pytest.raises(CalibrationError, match=r"bad\.csv: " + match):
        read_log(path)


def test_non_monotonic_timestamps_and_cli_exit_code(tmp_path):
    rows = ["t,cmd_vx,cmd_vy,cmd_wz,odom_x,odom_y,odom_yaw"] + [f"{0.1 * i:.2f},0.1,0,0,0,0,0" for i in range(30)]
    rows[12] = "0.50,0.1,0,0,0,0,0"  # row 12 (file line 13) goes back in time
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(CalibrationError, match="not strictly increasing at row 13"):
        read_log(path)
    out = tmp_path / "dyn.yaml"
    tool = str(ROOT / "tools" / "identify_dynamics.py")
    proc = subprocess.run([sys.executable, tool, str(path), "--out", str(out)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and "bad.csv" in proc.stderr and "strictly increasing" in proc.stderr
    assert not out.exists() and not list(tmp_path.glob(".dyn*"))
