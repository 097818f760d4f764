"""Training: a short smoke run, kill-and-resume, config validation, bad run directories and models."""

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.params import ConfigError
from ssbl_pb.training.config import load_config

ROOT = Path(__file__).resolve().parents[1]
TRAIN = [sys.executable, str(ROOT / "tools" / "train_pb.py")]
SMALL = ["--n-envs", "2", "--set", "ppo.n_steps=64", "--set", "ppo.batch_size=64", "--set", "ppo.n_epochs=1",
         "--set", "ppo.net_arch=[32,32]", "--set", "eval_every=256", "--set", "eval_episodes=2",
         "--set", "baseline_episodes=1", "--set", "checkpoint_every=256"]


def test_smoke_run_writes_a_complete_run_dir(tmp_path):
    out = tmp_path / "run"
    res = subprocess.run([*TRAIN, "--total-steps", "512", "--out", str(out), *SMALL], capture_output=True,
                         text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    for f in ("config.yaml", "model.zip", "vecnormalize.pkl", "learning_curve.csv", "learning_curve.png",
              "summary.json", "baselines.json", "eval.csv", "best/model.zip", "best/vecnormalize.pkl"):
        assert (out / f).is_file(), f
    assert json.loads((out / "summary.json").read_text())["steps"] == 512
    assert list((out / "tb").iterdir())
    # the run loads as a policy and acts
    from ssbl_pb.agents.trained import load_trained
    from ssbl_pb.env.gymenv.approach import ApproachGroupEnv

    env = ApproachGroupEnv()
    pol = load_trained(str(out), env.observation_space)
    obs, _ = env.reset(seed=0)
    action, _ = pol.predict(obs)
    assert action.shape == (2,)
    # a second start in the same directory is refused, nothing overwritten
    before = (out / "model.zip").read_bytes()
    res = subprocess.run([*TRAIN, "--total-steps", "512", "--out", str(out), *SMALL], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 2 and "already holds a run" in res.stderr
    assert (out / "model.zip").read_bytes() == before
    # fine-tuning starts from the run's weights
    from ssbl_pb.training.config import load_config as load
    from ssbl_pb.training.run import _init_from, build_model, make_vec_env

    cfg = load(out / "config.yaml")
    venv = make_vec_env(cfg, 0)
    fresh = build_model(cfg, venv, tmp_path / "tb")
    venv = _init_from(fresh, venv, out)
    a = fresh.policy.state_dict()
    b = pol.model.policy.state_dict()
    assert all(np.allclose(a[k].numpy(), b[k].numpy()) for k in b)
    assert np.allclose(venv.obs_rms.mean, pol.normalizer.obs_rms.mean)
    venv.close()
    # ... and with ppo.restart_std its action std starts again there, the rest as the source's
    venv = make_vec_env(cfg, 0)
    again = build_model(cfg, venv, tmp_path / "tb")
    _init_from(again, venv, out, 0.22)
    c = again.policy.state_dict()
    assert np.allclose(c["log_std"].numpy(), math.log(0.22))
    assert all(np.allclose(c[k].numpy(), b[k].numpy()) for k in b if k != "log_std")
    venv.close()


def test_kill_and_resume_continues_the_step_count(tmp_path):
    out = tmp_path / "run"
    total = 3072
    proc = subprocess.Popen([*TRAIN, "--total-steps", str(total), "--out", str(out), *SMALL],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    latest = out / "checkpoints" / "latest.json"
    deadline = time.time() + 180
    while time.time() < deadline and not (latest.exists() and json.loads(latest.read_text())["step"] >= 1024):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert latest.exists(), "no checkpoint written before the kill"
    step = json.loads(latest.read_text())["step"]
    assert step < total
    assert not (out / "summary.json").exists()
    res = subprocess.run([*TRAIN, "--resume", str(out)], capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["resumed_from"] == step and summary["steps"] == total
    steps = [int(line.split(",")[0]) for line in (out / "learning_curve.csv").read_text().splitlines()[1:]]
    assert steps == sorted(steps) and steps[-1] > step


def test_a_learning_rate_in_e_notation_is_a_number_in_files_and_on_the_command_line(tmp_path):
    from ssbl_pb.params import parse_yaml
    from ssbl_pb.training.config import parse_overrides

    cfg = tmp_path / "c.yaml"
    cfg.write_text("ppo:\n  learning_rate: 3e-5\n  learning_rate_end: 1E-6\nn_envs: 2\nname: 1e3x\n")
    loaded = load_config(cfg)
    assert loaded.ppo.learning_rate == 3e-5 and loaded.ppo.learning_rate_end == 1e-6 and loaded.n_envs == 2
    assert parse_overrides(["ppo.learning_rate=2e-4"]) == {"ppo": {"learning_rate": 2e-4}}
    # YAML's own forms keep their meaning: integers, dotted floats, words that merely start with digits
    assert parse_yaml("a: 3\nb: 3.0e-5\nc: 1e3x\nd: '3e-5'\ne: -2e+2") == {"a": 3, "b": 3e-5, "c": "1e3x",
                                                                           "d": "3e-5", "e": -200.0}


def test_resume_without_checkpoint(tmp_path):
    (tmp_path / "config.yaml").write_text("name: x\n")
    res = subprocess.run([*TRAIN, "--resume", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "no checkpoint" in res.stderr


def test_unknown_config_key_named(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("obs_mode: vector\nlearning_rat: 0.1\n")
    with pytest.raises(ConfigError, match="learning_rat"):
        load_config(cfg)
    res = subprocess.run([*TRAIN, "--config", str(cfg), "--out", str(tmp_path / "o")], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 2 and "learning_rat" in res.stderr
    assert not (tmp_path / "o").exists()


def test_observation_normalisation_can_be_turned_off(tmp_path):
    from ssbl_pb.training.run import make_vec_env

    for on in (True, False):
        venv = make_vec_env(load_config(None, {"n_envs": 1, "normalize_obs": on}), 0)
        obs = venv.reset()
        raw = venv.get_original_obs()
        assert venv.norm_obs is on and np.array_equal(obs, raw) is not on
        venv.close()
    with pytest.raises(ConfigError, match="normalize_obs"):
        load_config(None, {"normalize_obs": "no"})
    # unset: the vector standardised, a frozen encoder's features (the shipped SAEV here) raw
    assert load_config(None, {}).standardises_obs is True
    venv = make_vec_env(load_config(None, {"n_envs": 1}), 0)  # and training builds what it says
    assert venv.norm_obs is True
    venv.close()
    encoded = load_config(None, {"obs_mode": "camera_speed", "encoder": "saev", "camera_size": 64})
    assert encoded.standardises_obs is False
    assert load_config(None, {"obs_mode": "camera_speed", "encoder": "saev", "camera_size": 64,
                              "normalize_obs": True}).standardises_obs is True


def test_camera_mode_needs_an_existing_encoder():
    with pytest.raises(ConfigError, match="encoder"):
        load_config(None, {"obs_mode": "camera"})
    with pytest.raises(ConfigError, match="saev"):
        load_config(None, {"obs_mode": "camera", "encoder": "saev"})
    assert load_config(None, {"obs_mode": "camera", "encoder": "cnn"}).encoder == "cnn"


def test_bad_reward_weight_named():
    with pytest.raises(ConfigError, match="w_slott"):
        load_config(None, {"reward": {"w_slott": 1.0}})


def test_a_ramped_weight_set_to_another_value_is_refused_not_ignored():
    ff = Path(__file__).resolve().parents[1] / "configs" / "vector_ff.yaml"
    with pytest.raises(ConfigError, match=r"reward.w_smooth = 0.3: expected 0.05, the start of reward_ramp.w_smooth"):
        load_config(ff, {"reward": {"w_smooth": 0.3}})
    cfg = load_config(ff, {"reward": {"w_smooth": 0.3}, "reward_ramp": {}})  # an empty mapping clears the ramp
    assert cfg.reward["w_smooth"] == 0.3 and cfg.reward_ramp == {}
    assert load_config(ff, {"reward_ramp": {"w_smooth": [0.05, 0.9]}}).reward_ramp["w_smooth"] == [0.05, 0.9]


def test_corrupt_model_file(tmp_path):
    from ssbl_pb.agents.trained import ModelError, load_trained

    bad = tmp_path / "model.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ModelError, match="not a saved SB3 model"):
        load_trained(str(bad))


def test_camera_speed_cnn_trains(tmp_path):
    out = tmp_path / "cam"
    res = subprocess.run([*TRAIN, "--config", str(ROOT / "configs" / "camera_cnn.yaml"), "--total-steps", "128",
                          "--out", str(out), "--n-envs", "1", "--set", "ppo.n_steps=128", "--set",
                          "ppo.batch_size=64", "--set", "ppo.n_epochs=1", "--set", "eval_every=128", "--set",
                          "eval_episodes=1", "--set", "baseline_episodes=1", "--set", "camera_size=48"],
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    from ssbl_pb.agents.trained import load_trained
    from ssbl_pb.env.gymenv.approach import make_env

    env = make_env(obs_mode="camera_speed", camera_width=48, camera_height=48)
    pol = load_trained(str(out), env.observation_space)
    obs, _ = env.reset(seed=0)
    assert pol.predict(obs)[0].shape == (2,)
    with pytest.raises(ValueError, match="trained for observations"):
        load_trained(str(out), make_env().observation_space)


def test_bounded_mean_policy_keeps_the_mean_in_the_box_and_loads_back(tmp_path):
    import torch
    from stable_baselines3 import PPO

    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.training.policies import BoundedMlpPolicy

    model = PPO(BoundedMlpPolicy, make_env(), n_steps=64, batch_size=64, seed=0, device="cpu")
    with torch.no_grad():  # a head that would put the plain mean far outside [-1, 1]
        model.policy.action_net[0].weight.fill_(0.0)
        model.policy.action_net[0].bias.copy_(torch.tensor([50.0, -50.0]))
    obs = torch.ones((4, model.observation_space.shape[0]))
    mean = model.policy.get_distribution(obs).distribution.mean
    assert torch.allclose(mean, torch.tensor([1.0, -1.0]).expand(4, 2))  # tanh(+-50), not +-50
    model.save(tmp_path / "m.zip")
    back = PPO.load(tmp_path / "m.zip", device="cpu")
    assert type(back.policy) is BoundedMlpPolicy
    assert torch.allclose(back.policy.get_distribution(obs).distribution.mean, mean)


def test_build_model_bounded_by_default_plain_on_request(tmp_path):
    from stable_baselines3.common.policies import ActorCriticPolicy

    from ssbl_pb.training.policies import BoundedMlpPolicy
    from ssbl_pb.training.run import build_model, make_vec_env

    for bounded, cls in ((True, BoundedMlpPolicy), (False, ActorCriticPolicy)):
        cfg = load_config(None, {"n_envs": 1, "ppo": {"bounded_mean": bounded}})
        model = build_model(cfg, make_vec_env(cfg, 0), tmp_path / "tb")
        assert type(model.policy) is cls
    with pytest.raises(ConfigError, match="bounded_mean"):
        load_config(None, {"ppo": {"bounded_mean": "yes"}})


def test_learning_rate_anneals_linearly_to_its_end_value(tmp_path):
    from ssbl_pb.training.run import build_model, make_vec_env

    cfg = load_config(None, {"n_envs": 1, "ppo": {"learning_rate": 3e-4, "learning_rate_end": 3e-5}})
    model = build_model(cfg, make_vec_env(cfg, 0), tmp_path / "tb")
    # SB3's schedules take the progress remaining: 1 at the start, 0 at the end
    assert [model.lr_schedule(x) for x in (1.0, 0.5, 0.0)] == pytest.approx([3e-4, 1.65e-4, 3e-5])
    constant = build_model(load_config(None, {"n_envs": 1}), make_vec_env(cfg, 0), tmp_path / "tb")
    assert constant.lr_schedule(0.0) == pytest.approx(3e-4)
    with pytest.raises(ConfigError, match="learning_rate_end"):
        load_config(None, {"ppo": {"learning_rate_end": 2}})
    with pytest.raises(ConfigError, match=r"ppo.restart_std = 0: expected a number in \(0, 1\] or null"):
        load_config(None, {"ppo": {"restart_std": 0}})


def test_fine_tuning_across_plain_and_bounded_heads_keeps_the_weights():
    import torch

    from ssbl_pb.training.run import RunError, _match_action_head

    w, b = torch.ones(2, 8), torch.zeros(2)
    target = {"action_net.0.weight": torch.zeros(2, 8), "action_net.0.bias": torch.zeros(2), "log_std": torch.zeros(2)}
    out = _match_action_head({"action_net.weight": w, "action_net.bias": b, "log_std": torch.ones(2)}, target)
    assert out["action_net.0.weight"] is w and "action_net.weight" not in out
    with pytest.raises(RunError, match="net_arch"):
        _match_action_head({"action_net.weight": torch.ones(2, 16), "action_net.bias": b, "log_std": b}, target)


def test_ctrl_c_saves_a_checkpoint_and_says_how_to_resume(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([*TRAIN, "--total-steps", "200000", "--out", str(out), *SMALL],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = out / "checkpoints" / "latest.json"
    deadline = time.time() + 120
    while time.time() < deadline and not first.exists():  # the initial state is checkpointed before training
        time.sleep(0.1)
    assert first.exists() and json.loads(first.read_text())["step"] == 0
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and f"--resume {out}" in err
    step = json.loads(first.read_text())["step"]
    assert step > 0 and (out / "checkpoints" / f"ckpt_{step:09d}.zip").is_file()
    assert not (out / "summary.json").exists()


def test_resume_of_a_finished_run_changes_nothing_and_overwrite_replaces_only_the_run(tmp_path):
    out = tmp_path / "run"
    res = subprocess.run([*TRAIN, "--total-steps", "512", "--out", str(out), *SMALL], capture_output=True,
                         text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    res = subprocess.run([*TRAIN, "--resume", str(out)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "already finished" in res.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files
    (out / "best" / "eval.json").write_text(json.dumps({"score": 99.0, "success_rate": 1.0}))  # a stale best
    (out / "notes.txt").write_text("not written by the run")
    res = subprocess.run([*TRAIN, "--total-steps", "512", "--out", str(out), "--overwrite", *SMALL],
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (out / "notes.txt").read_text() == "not written by the run"  # --overwrite removes only the run's files
    best = json.loads((out / "best" / "eval.json").read_text())
    assert best["score"] < 99.0  # a new best was saved, not compared against the old run's
    summary = json.loads((out / "summary.json").read_text())
    assert summary["best_eval"] == best


def test_policy_flag_picks_its_config_and_a_run_name_of_its_own():
    from ssbl_pb.training.config import run_name

    ff = load_config(ROOT / "configs" / "vector_ff.yaml")
    as_lstm = load_config(ROOT / "configs" / "vector_ff.yaml", {"policy": "lstm"})
    assert run_name(as_lstm, ff, named=False).name == "ppo_vector_lstm"
    assert run_name(as_lstm, ff, named=True).name == ff.name
    assert run_name(ff, ff, named=False).name == ff.name


def test_env_keys_are_checked_before_any_output(tmp_path):
    with pytest.raises(ConfigError, match=r"config.env = \['bogus'\]"):
        load_config(None, {"env": {"bogus": 1}})


def test_copy_policy_brings_the_encoder_along(tmp_path):
    import yaml

    from ssbl_pb.agents.trained import copy_policy, policy_env_kwargs

    run, enc, dest = tmp_path / "run", tmp_path / "elsewhere" / "saev.pt", tmp_path / "shipped"
    for folder in (run, enc.parent, dest):
        folder.mkdir()
    enc.write_bytes(b"weights")
    (run / "model.zip").write_bytes(b"zip")
    (run / "vecnormalize.pkl").write_bytes(b"norm")
    (run / "config.yaml").write_text(yaml.safe_dump({"obs_mode": "camera_speed", "encoder": "saev",
                                                     "encoder_checkpoint": str(enc), "camera_size": 64}))
    assert copy_policy(str(run), dest) == ["model.zip", "vecnormalize.pkl", "config.yaml", "encoder.pt"]
    assert (dest / "encoder.pt").read_bytes() == b"weights"
    assert yaml.safe_load((dest / "config.yaml").read_text())["encoder_checkpoint"] == "encoder.pt"
    enc.unlink()  # the shipped folder stands alone
    assert policy_env_kwargs(str(dest)) == {"obs_mode": "camera_speed", "camera_width": 64, "camera_height": 64,
                                            "encoder": str(dest / "encoder.pt")}


def test_fine_tuning_onto_the_range_scan_starts_as_the_source(tmp_path):
    """``--init-from`` a 40-entry Vector policy (trained without the range scan) into a config whose observation
    has it: the new inputs' weights start at zero and the source's normalisation is kept for the old entries, so
    the fine-tuned model acts exactly as the source."""
    import torch

    from ssbl_pb.agents.trained import load_trained
    from ssbl_pb.core import observation as ob
    from ssbl_pb.training.run import _init_from, build_model, make_vec_env

    src_dir = tmp_path / "no_scan"
    res = subprocess.run([*TRAIN, "--total-steps", "256", "--out", str(src_dir), *SMALL, "--set", "env.scan=false"],
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    src = load_trained(str(src_dir), None)
    assert src.observation_space.shape == (ob.BASE_SIZE,)
    cfg = load_config(None, {"n_envs": 2, "scenario": "default@furnished", "ppo": {"net_arch": [32, 32]}})
    venv = make_vec_env(cfg, 0)
    model = build_model(cfg, venv, tmp_path / "tb")
    new = _init_from(model, venv, src_dir)
    assert new.observation_space.shape == (ob.OBS_SIZE,) and new.obs_rms.mean.shape == (ob.OBS_SIZE,)
    assert np.allclose(new.obs_rms.mean[:ob.BASE_SIZE], src.normalizer.obs_rms.mean)
    first = model.policy.state_dict()["mlp_extractor.policy_net.0.weight"]
    assert first.shape[1] == ob.OBS_SIZE and torch.all(first[:, ob.BASE_SIZE:] == 0)
    obs = venv.venv.reset()
    assert np.all(obs[:, ob.BASE_SIZE:] <= 1.0) and np.any(obs[:, ob.BASE_SIZE:] < 1.0)
    mine, _ = model.predict(new.normalize_obs(obs), deterministic=True)
    theirs, _ = src.model.predict(src.normalize(obs[:, :ob.BASE_SIZE]), deterministic=True)
    assert np.allclose(mine, theirs, atol=1e-6)
