"""Human-motion statistics: ETH/UCY figures, the fitted SocialParams, the SFFM side, bad input."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.calib.humans import fit_social, load_scene, real_stats, scene_stats, sim_stats
from ssbl_pb.params import CalibrationError, SocialParams, from_dict, load_yaml

ROOT = Path(__file__).resolve().parents[1]


def test_scene_stats_on_a_tiny_fixture(tmp_path):
    """Two group members 0.8 m apart walking at 1.2 m/s; a stranger passing 2 m away at its closest."""
    rows = []
    for f in range(10):
        x = 1.2 * 0.4 * f
        rows += [[f, 1, x, 0, 0.0, 1.2, 0, 0], [f, 2, x, 0, 0.8, 1.2, 0, 0],
                 [f, 3, 5.0 - x, 0, 2.8, -1.2, 0, 0]]
    (tmp_path / "obsmat.txt").write_text("\n".join(" ".join(str(v) for v in r) for r in rows) + "\n")
    (tmp_path / "groups.txt").write_text("1 2\n")
    st = scene_stats(load_scene(tmp_path))
    assert st["group_distance"] == pytest.approx(np.full(20, 0.8))
    assert st["walking_speed"] == pytest.approx(np.full(30, 1.2))
    assert sorted(st["stranger_distance"]) == pytest.approx([2.0, 2.8], abs=0.25)


def test_real_eth_ucy_statistics_and_fit(shared_data):
    real = real_stats(shared_data / "trajectories" / "eth_ucy_raw")
    pooled = real["all"]
    assert np.median(pooled["group_distance"]) == pytest.approx(0.71, abs=0.03)
    assert np.median(pooled["walking_speed"]) == pytest.approx(1.16, abs=0.03)
    assert np.median(real["ewap_seq_eth"]["walking_speed"]) == pytest.approx(1.50, abs=0.05)
    fields, notes = fit_social(pooled)
    assert fields["personal_radius"] == pytest.approx(1.09, abs=0.03)
    assert fields["min_member_gap"] == pytest.approx(fields["personal_radius"] + 0.05, abs=1e-3)
    assert any("inside the fitted personal radius" in n for n in notes)
    from_dict(SocialParams, fields)  # the env can load them


def test_sim_statistics_follow_the_params():
    s = SocialParams()
    st = sim_stats(s, episodes=8, seconds=8.0, seed=0)
    assert np.median(st["group_distance"]) == pytest.approx(s.min_member_gap, abs=0.1)
    assert np.all(st["walking_speed"] <= s.max_speed + 1e-9)
    assert len(st["stranger_distance"]) == 8


def test_bad_input(tmp_path):
    with pytest.raises(CalibrationError, match="no obsmat"):
        load_scene(tmp_path)
    (tmp_path / "obsmat.txt").write_text("1 2 3\n")
    with pytest.raises(CalibrationError, match=r"obsmat\.txt: 3 columns"):
        load_scene(tmp_path)
    out = tmp_path / "h.yaml"
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "calibrate_humans.py"), "--data",
                           str(tmp_path / "none"), "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "none: data folder not found" in proc.stderr and not out.exists()


def test_cli_output_loads(shared_data, tmp_path):
    out = tmp_path / "humans.yaml"
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "calibrate_humans.py"), "--out", str(out),
                           "--episodes", "4", "--scenes", "ewap_seq_hotel", "ucy_zara01",
                           "--data", str(shared_data / "trajectories" / "eth_ucy_raw")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    from_dict(SocialParams, load_yaml(out))
    assert out.with_suffix(".png").is_file() and "SFFM fitted" in out.with_suffix(".md").read_text()
