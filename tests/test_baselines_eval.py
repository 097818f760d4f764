"""Baselines and the evaluation tool: behaviour, determinism, files, bad input."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.agents.policies import SFFMPolicy, StraightPolicy, make_policy
from ssbl_pb.agents.rollout import run_episode
from ssbl_pb.analysis.evaluation import Setup, evaluate
from ssbl_pb.core.observation import OBS_SIZE
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def test_sffm_joins_the_default_group():
    env = ApproachGroupEnv(record=True)
    pol = make_policy("sffm")
    wins = [run_episode(env, pol, 2000 + i).metrics["success"] for i in range(6)]
    assert sum(wins) >= 5


def test_sffm_force_points_toward_the_group_from_afar():
    env = ApproachGroupEnv()
    obs, _ = env.reset(seed=11)
    f = SFFMPolicy().force(obs)
    centre = obs[2:4]
    assert np.dot(f, centre) > 0


def test_straight_policy_brakes_near_the_slot():
    pol = StraightPolicy()
    far = np.zeros(OBS_SIZE, dtype=np.float32)
    far[0:2] = (1.0, 0.0)  # 5 m ahead
    near = far.copy()
    near[0:2] = (0.02, 0.0)  # 0.1 m ahead
    assert pol.act(far)[0] == pytest.approx(1.0)
    assert 0 < pol.act(near)[0] < 0.6


def test_random_policy_fails():
    env = ApproachGroupEnv(record=True)
    pol = make_policy("random", seed=0)
    assert sum(run_episode(env, pol, 3000 + i).metrics["success"] for i in range(3)) == 0


def test_unknown_policy_name():
    with pytest.raises(ValueError, match="policy 'magic'"):
        make_policy("magic")


def test_evaluate_same_seed_same_files(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    evaluate(Setup("straight"), 4, 7, a, workers=1, n_paths=2)
    evaluate(Setup("straight"), 4, 7, b, workers=2, n_paths=2)
    assert (a / "episodes.csv").read_text() == (b / "episodes.csv").read_text()
    summary = json.loads((a / "summary.json").read_text())
    for key in ("success_rate", "collision_rate", "mean_return", "personal_zone_time_s", "human_displacement_m",
                "mean_jerk", "arrival_speed"):
        assert key in summary
    assert (a / "paths.png").stat().st_size > 1000
    assert not list(a.glob(".staging*"))


def test_a_network_policy_gives_the_same_bytes_with_any_number_of_workers(tmp_path):
    """The shipped network plays its episodes in batches; batches of other sizes round its forward pass
    differently, so the batches must not depend on the workers."""
    a, b = tmp_path / "a", tmp_path / "b"
    evaluate(Setup("vector"), 16, 1000, a, workers=1, n_paths=0)
    evaluate(Setup("vector"), 16, 1000, b, workers=2, n_paths=0)
    assert (a / "episodes.csv").read_bytes() == (b / "episodes.csv").read_bytes()
    assert (a / "summary.json").read_bytes() == (b / "summary.json").read_bytes()


def test_the_summary_records_whether_the_observation_model_was_on(tmp_path):
    from test_contracts import run_in_process

    for flag, says in (("on", "on (movenet)"), ("colour", "on (colour)"), ("off", "off")):
        out = tmp_path / flag
        res = run_in_process(ROOT / "tools" / "evaluate.py", ["--policy", "sffm", "--episodes", "2", "--paths", "0",
                                                             "--workers", "1", "--perception", flag, "--out", str(out)])
        assert res.returncode == 0, res.stderr
        assert json.loads((out / "summary.json").read_text())["perception"] == says
        assert res.stdout.startswith(f"perception {says}  success "), res.stdout


def run_cli(*args):
    return subprocess.run([sys.executable, str(ROOT / "tools" / "evaluate.py"), *args], capture_output=True,
                          text=True, timeout=120)


@pytest.mark.parametrize("args,message", [
    (["--policy", "magic"], "--policy 'magic'"),
    (["--policy", "nope/model.zip"], "--policy 'nope/model.zip'"),
    (["--policy", "sffm", "--episodes", "0"], "argument --episodes: 0: expected an integer >= 1"),
    (["--policy", "sffm", "--against", "nowhere"], "nowhere/episodes.csv: cannot read an evaluation's episodes"),
])
def test_cli_bad_input(tmp_path, args, message):
    out = tmp_path / "out"
    res = run_cli(*args, "--out", str(out))
    assert res.returncode == 2
    assert message in res.stderr
    assert not (out / "episodes.csv").exists()


def test_cli_groups_flag_spawns_the_papers_circles(tmp_path):
    res = run_cli("--policy", "sffm", "--groups", "paper", "--episodes", "2", "--workers", "1", "--paths", "0",
                  "--out", str(tmp_path / "cli"))
    assert res.returncode == 0, res.stderr
    evaluate(Setup("sffm", env_kwargs=(("groups", "paper"),)), 2, 1000, tmp_path / "paper", n_paths=0)
    evaluate(Setup("sffm"), 2, 1000, tmp_path / "calibrated", n_paths=0)
    played = (tmp_path / "cli" / "episodes.csv").read_text()
    assert played == (tmp_path / "paper" / "episodes.csv").read_text()  # the paper's groups, same episodes
    assert played != (tmp_path / "calibrated" / "episodes.csv").read_text()
    res = run_cli("--policy", "sffm", "--groups", "circle", "--out", str(tmp_path / "x"))
    assert res.returncode == 2 and "--groups: invalid choice: 'circle'" in res.stderr


def test_cli_unwritable_out(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = run_cli("--policy", "sffm", "--episodes", "1", "--out", str(blocker / "sub"))
    assert res.returncode == 2 and "is a file, not a directory" in res.stderr


def test_baseline_needs_vector_obs(tmp_path):
    with pytest.raises(UserError, match="--obs-mode vector"):
        evaluate(Setup("sffm", obs_mode="camera"), 1, 0, tmp_path)


def test_shipped_vector_policy_joins_the_group():
    from ssbl_pb.agents.trained import load_trained

    env = ApproachGroupEnv(record=True)
    pol = load_trained("vector", env.observation_space)
    assert pol.filter is not None  # the agent's action smoothing travels with the model
    wins = [run_episode(env, pol, 500_000 + i).metrics["success"] for i in range(4)]
    assert sum(wins) >= 3


def test_compare_marks_the_better_side():
    from ssbl_pb.analysis.compare import compare_rows

    learned = [{"success": 1.0, "mean_jerk": 0.1 + 0.01 * i, "n_humans": 2.0} for i in range(20)]
    baseline = [{"success": 1.0, "mean_jerk": 0.3 + 0.01 * i, "n_humans": 3.0} for i in range(20)]
    cmp = compare_rows(learned, baseline)
    assert cmp["mean_jerk"]["better"] == "learned" and cmp["mean_jerk"]["test"]["p"] < 0.05
    assert cmp["success"]["better"] is None  # no discordant pairs
    both = compare_rows([{"obstacle_collision": float(i < 9)} for i in range(20)],
                        [{"obstacle_collision": 0.0} for _ in range(20)])["obstacle_collision"]
    assert both["test"]["test"] == "mcnemar" and both["test"]["a_only"] == 9 and both["better"] == "baseline"
    assert cmp["n_humans"]["better"] is None  # descriptive: no direction
    assert compare_rows(baseline, learned)["mean_jerk"]["better"] == "baseline"
    # 19 pairs a little lower, one far higher (mean higher): lower in the rank test's terms, not by the mean, so
    # neither side is better
    skew_l = [{"human_displacement_m": 0.10 - 0.001 * i if i else 1.0} for i in range(20)]
    skew_b = [{"human_displacement_m": 0.11 - 0.001 * i} for i in range(20)]
    skew = compare_rows(skew_l, skew_b)["human_displacement_m"]
    assert skew["learned"]["mean"] > skew["baseline"]["mean"] and skew["test"]["mean_diff"] > 0
    assert skew["test"]["effect"] < 0 and skew["test"]["p"] < 0.05 and skew["better"] is None
    skew_l[0]["human_displacement_m"] = 0.105  # the tail gone: the mean agrees with the test
    assert compare_rows(skew_l, skew_b)["human_displacement_m"]["better"] == "learned"


def test_path_panels_show_the_place_and_the_o_space() -> None:
    from ssbl_pb.analysis.report import view_bounds

    # the robot stays east of the members; the place lies 2 m west of them (seed 500495 of `mixed` was cut off)
    robot = np.array([[3.0, 0.0], [1.0, 0.0]])
    members = np.array([[[0.0, 1.0], [0.0, -1.0]]])
    (x0, x1), (y0, y1) = view_bounds(robot, members, slot=(-2.0, 0.0), centre=(-0.5, 0.0), radius=1.0)
    # x from the place (-2) to the start (3), each 1 m out: [-3, 4]; y widened to the same 7 m, centred on 0
    assert (x0, x1) == pytest.approx((-3.0, 4.0)) and (y0, y1) == pytest.approx((-3.5, 3.5))


def test_against_pairs_two_evaluations_seed_by_seed_and_refuses_other_seeds(tmp_path):
    """``--against DIR``: the straight-line policy against the SFFM on the same 3 starts; the pairs counted by hand
    from both episodes.csv files, and an evaluation of other seeds refused before anything is written."""
    from test_contracts import run_in_process

    common = ["--episodes", "3", "--paths", "0", "--workers", "1", "--seed", "1000"]
    a, b = tmp_path / "sffm", tmp_path / "straight"
    tool = ROOT / "tools" / "evaluate.py"
    assert run_in_process(tool, ["--policy", "sffm", *common, "--out", str(a)]).returncode == 0
    res = run_in_process(ROOT / "tools" / "evaluate.py", ["--policy", "straight", *common, "--out", str(b),
                                                         "--against", str(a)])
    assert res.returncode == 0, res.stderr
    ok = {d: {int(r["seed"]): float(r["success"]) for r in csv.DictReader(open(d / "episodes.csv"))} for d in (a, b)}
    gained = sum(ok[b][s] == 1 and ok[a][s] == 0 for s in ok[a])
    lost = sum(ok[b][s] == 0 and ok[a][s] == 1 for s in ok[a])
    versus = json.loads((b / "summary.json").read_text())["against"]
    assert (versus["against"], versus["gained"], versus["lost"]) == (str(a), gained, lost)
    assert f"against {a}: joined {gained} it did not, lost {lost} it joined" in res.stdout
    c = tmp_path / "other_seeds"
    res = run_in_process(ROOT / "tools" / "evaluate.py", ["--policy", "straight", "--episodes", "2", "--seed", "5",
                                                         "--workers", "1", "--out", str(c), "--against", str(a)])
    assert res.returncode != 0 and "no episodes with seeds [5, 6]" in res.stderr and "1000-1002" in res.stderr
    assert not c.exists()
