"""Camera modes through a frozen autoencoder (env/gymenv/encoded.py): the wrappers, the frozen encoder inside SB3,
training with encoder conv / saev and evaluating the result (training/config.py, run.py, evaluation.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from ssbl_pb.env.gymenv.approach import make_env
from ssbl_pb.env.gymenv.encoded import EncodedVecEnv, FrozenEncoder, load_encoder
from ssbl_pb.errors import UserError
from ssbl_pb.params import ConfigError
from ssbl_pb.perception.autoencoding import autoencoders as A
from ssbl_pb.perception.autoencoding.ae_train import save_checkpoint
from ssbl_pb.training.config import load_config

TINY = A.AESize("tiny", 24, (4, 6, 5), (3, 3, 3), 2, 12, (4, 4), 8, 6)


@pytest.fixture
def checkpoints(tmp_path: Path) -> dict[str, Path]:
    torch.manual_seed(0)
    out = {}
    for arch in A.ARCHS:
        model = A.build(arch, TINY).train()
        model(torch.rand(8, 3, 24, 24))  # move the BatchNorm running statistics off their initial values
        out[arch] = save_checkpoint(tmp_path / f"{arch}.pt", model.eval())
    return out


def _state(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in module.state_dict().items()}


def test_single_and_batched_wrappers_emit_the_same_features(checkpoints: dict[str, Path]) -> None:
    from stable_baselines3.common.vec_env import DummyVecEnv

    path = str(checkpoints["saev"])
    single = make_env(obs_mode="camera_speed", camera_width=24, camera_height=24, encoder=path,
                      task={"max_steps": 4})
    obs, _ = single.reset(seed=7)
    assert obs.shape == (3 * 5 + 2,) == single.observation_space.shape and obs.dtype == np.float32
    venv = DummyVecEnv([lambda: make_env(obs_mode="camera_speed", camera_width=24, camera_height=24,
                                         task={"max_steps": 4})] * 2)
    venv.seed(7)
    enc = EncodedVecEnv(venv, load_encoder(path, 24))
    assert enc.observation_space == single.observation_space  # a model trained on one runs on the other
    batch = enc.reset()
    assert np.allclose(batch[0], obs, atol=1e-5)
    xy, rho = obs[:15].reshape(5, 3)[:, :2], obs[:15].reshape(5, 3)[:, 2]
    assert np.all(np.abs(xy) <= 1) and np.all((rho >= 0) & (rho <= 1))
    a = np.zeros((2, 2), np.float32)
    for _ in range(4):  # the time limit ends both episodes on the 4th step
        batch, _, dones, infos = enc.step(a)
        single_obs, *_ = single.step(a[0])
    assert dones.all()
    assert infos[0]["terminal_observation"].shape == (17,)
    assert np.allclose(infos[0]["terminal_observation"], single_obs, atol=1e-5)


def _ema(raw: list[np.ndarray], alpha: float) -> list[np.ndarray]:
    """The low-pass ``y_t = y_{t-1} + alpha (x_t - y_{t-1})`` of one episode's features, by hand."""
    out = [raw[0]]
    for x in raw[1:]:
        out.append(out[-1] + alpha * (x - out[-1]))
    return out


def test_feature_smoothing_low_passes_the_code_within_each_episode(checkpoints: dict[str, Path]) -> None:
    from stable_baselines3.common.vec_env import DummyVecEnv

    path, alpha = str(checkpoints["saev"]), 0.25

    def venv() -> DummyVecEnv:  # env 0 ends after 3 steps, env 1 after 5: one restarts while the other goes on
        v = DummyVecEnv([lambda n=n: make_env(obs_mode="camera_speed", camera_width=24, camera_height=24,
                                              task={"max_steps": n}) for n in (3, 5)])
        v.seed(3)
        return v

    raw, low = EncodedVecEnv(venv(), load_encoder(path, 24)), EncodedVecEnv(venv(), load_encoder(path, 24), alpha)
    a = np.zeros((2, 2), np.float32)  # the actions do not depend on the features: both runs see the same frames
    seen_raw, seen_low, last_raw, last_low = [raw.reset()], [low.reset()], [], []
    for _ in range(5):
        r, _, d_raw, i_raw = raw.step(a)
        f, _, d_low, i_low = low.step(a)
        assert (d_raw == d_low).all()
        seen_raw.append(r)
        seen_low.append(f)
        if d_raw[0] and len(last_raw) == 0:
            last_raw.append(i_raw[0]["terminal_observation"])
            last_low.append(i_low[0]["terminal_observation"])
    assert np.allclose(seen_low[0], seen_raw[0])  # the first frame passes unfiltered
    code = slice(0, 15)  # the speed (last two entries) is not filtered
    ep1 = _ema([o[1, code] for o in seen_raw[:5]] + [seen_raw[5][1, code]], alpha)[:5]
    assert np.allclose([o[1, code] for o in seen_low[:5]], ep1, atol=1e-5)
    assert np.allclose([o[:, 15:] for o in seen_low], [o[:, 15:] for o in seen_raw])
    ep0 = _ema([seen_raw[t][0, code] for t in range(3)] + [last_raw[0][code]], alpha)
    assert np.allclose([seen_low[t][0, code] for t in range(3)], ep0[:3], atol=1e-5)
    assert np.allclose(last_low[0][code], ep0[3], atol=1e-5)  # the last frame with its episode's past
    assert not np.allclose(last_low[0][code], last_raw[0][code], atol=1e-3)
    assert np.allclose(seen_low[3][0], seen_raw[3][0])  # env 0's next episode starts afresh
    assert np.allclose(seen_low[4][0, code], _ema([seen_raw[3][0, code], seen_raw[4][0, code]], alpha)[1],
                       atol=1e-5)

    single = make_env(obs_mode="camera_speed", camera_width=24, camera_height=24, encoder=path,
                      feature_smoothing=alpha, task={"max_steps": 5})
    obs = [single.reset(seed=4)[0]] + [single.step(a[1])[0] for _ in range(4)]  # DummyVecEnv seeds env 1 with 3+1
    assert np.allclose(obs, [o[1] for o in seen_low[:5]], atol=1e-5)  # the one-env wrapper filters alike
    assert np.allclose(single.reset(seed=4)[0], seen_low[0][1], atol=1e-5)  # reset forgets the last episode
    single.close()


def test_feature_smoothing_is_checked(checkpoints: dict[str, Path]) -> None:
    saev = str(checkpoints["saev"])
    cfg = {"obs_mode": "camera", "encoder": "saev", "encoder_checkpoint": saev, "camera_size": 24}
    assert load_config(None, cfg | {"feature_smoothing": 0.5}).feature_smoothing == 0.5
    with pytest.raises(ConfigError, match=r"feature_smoothing = 0: expected a number in \(0, 1\]"):
        load_config(None, cfg | {"feature_smoothing": 0})
    with pytest.raises(ConfigError, match=r"feature_smoothing = 0.5: expected 1 for encoder 'none'"):
        load_config(None, {"feature_smoothing": 0.5})
    with pytest.raises(UserError, match=r"feature_smoothing 1.5: expected a number in \(0, 1\]"):
        make_env(obs_mode="camera", camera_width=24, camera_height=24, encoder=saev, feature_smoothing=1.5)
    with pytest.raises(UserError, match=r"feature_smoothing 0.5: filters a frozen encoder's features"):
        make_env(obs_mode="camera", camera_width=24, camera_height=24, feature_smoothing=0.5)


def test_frozen_encoder_stays_in_eval_mode_when_its_owner_trains(checkpoints: dict[str, Path]) -> None:
    enc = load_encoder(checkpoints["conv"])
    owner = torch.nn.Sequential(torch.nn.Linear(2, 2), enc)
    owner.train()
    assert owner[0].training and not any(m.training for m in enc.modules())
    assert not any(p.requires_grad for p in enc.parameters())


@pytest.mark.parametrize("arch", A.ARCHS)
def test_sb3_updates_leave_the_encoder_untouched(checkpoints: dict[str, Path], tmp_path: Path, arch: str) -> None:
    from ssbl_pb.training.run import build_model, make_vec_env

    cfg = load_config(None, {"obs_mode": "camera", "encoder": arch, "encoder_checkpoint": str(checkpoints[arch]),
                             "camera_size": 24, "n_envs": 2, "ppo": {"n_steps": 16, "batch_size": 16,
                                                                     "n_epochs": 2}})
    venv = make_vec_env(cfg, 0)
    model = build_model(cfg, venv, tmp_path / "tb")
    encoded = venv.venv
    assert isinstance(encoded, EncodedVecEnv) and isinstance(encoded.encoder, FrozenEncoder)
    before = _state(encoded.encoder)
    model.learn(64)  # two PPO updates: policy.set_training_mode(True) before each
    assert not any(m.training for m in encoded.encoder.modules())
    after = encoded.encoder.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)  # BatchNorm running statistics included
    assert not any(p is q for p in model.policy.parameters() for q in encoded.encoder.parameters())
    venv.close()


def test_an_encoder_brings_the_camera_it_learned_through(checkpoints: dict[str, Path], tmp_path: Path) -> None:
    from ssbl_pb.training.run import _env_kwargs

    torch.manual_seed(0)
    narrow = save_checkpoint(tmp_path / "narrow.pt", A.build("saev", TINY).eval(),
                             {"summary": {"camera_hfov_deg": 26.5}})
    kw = {"obs_mode": "camera", "camera_width": 24, "camera_height": 24}
    env = make_env(**kw, encoder=str(narrow))
    assert env.unwrapped.robot_params.camera_hfov_deg == 26.5
    env.close()
    env = make_env(**kw, encoder=str(checkpoints["saev"]))  # recorded no camera: Pepper's
    assert env.unwrapped.robot_params.camera_hfov_deg == 56.3
    env.close()
    with pytest.raises(UserError, match=r"robot camera_hfov_deg 40.0: the encoder \S*narrow.pt learned from frames "
                                        r"of a 26.5 deg camera"):
        make_env(**kw, encoder=str(narrow), robot={"camera_hfov_deg": 40.0})
    cfg = {"obs_mode": "camera", "encoder": "saev", "encoder_checkpoint": str(narrow), "camera_size": 24}
    assert _env_kwargs(load_config(None, cfg))["robot"] == {"camera_hfov_deg": 26.5}  # training and evaluations
    with pytest.raises(ConfigError, match=r"config.env.robot camera_hfov_deg 40.0: the encoder"):
        load_config(None, cfg | {"env": {"robot": {"camera_hfov_deg": 40.0}}})


def _camera_yaml(path: Path, hfov_deg: float) -> str:
    """A ROS camera_info YAML of a 640x480 pinhole with the given horizontal field of view."""
    f = 320 / math.tan(math.radians(hfov_deg) / 2)
    path.write_text(f"image_width: 640\nimage_height: 480\ncamera_name: t\n"
                    f"camera_matrix: {{rows: 3, cols: 3, data: [{f}, 0.0, 319.5, 0.0, {f}, 239.5, 0.0, 0.0, 1.0]}}\n"
                    "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
    return str(path)


def test_a_calibrated_camera_must_be_the_encoders(checkpoints: dict[str, Path], tmp_path: Path) -> None:
    torch.manual_seed(0)
    narrow = str(save_checkpoint(tmp_path / "narrow.pt", A.build("saev", TINY).eval(),
                                 {"summary": {"camera_hfov_deg": 26.5}}))
    kw = {"obs_mode": "camera", "camera_width": 24, "camera_height": 24}
    pepper_like = _camera_yaml(tmp_path / "pepper.yaml", 58.0)  # tan ratio 1.033 to 56.3: within 5 %
    env = make_env(**kw, encoder=str(checkpoints["saev"]), camera_yaml=pepper_like)
    assert env.unwrapped.robot_params.camera_hfov_deg == pytest.approx(58.0, abs=0.01)  # the calibrated one
    env.close()
    with pytest.raises(UserError, match=r"camera_yaml \S*pepper.yaml: a 58.0 deg camera, the encoder \S*narrow.pt "
                                        r"learned from frames of a 26.5 deg camera \(people 0.42x"):
        make_env(**kw, encoder=narrow, camera_yaml=pepper_like)
    wide = _camera_yaml(tmp_path / "wide.yaml", 62.0)  # tan ratio 0.89 to Pepper's 56.3
    with pytest.raises(UserError, match=r"a 62.0 deg camera, the encoder \S*saev.pt learned from frames of a "
                                        r"56.3 deg camera \(people 0.89x"):
        make_env(**kw, encoder=str(checkpoints["saev"]), camera_yaml=wide)
    cfg = {"obs_mode": "camera", "encoder": "saev", "encoder_checkpoint": narrow, "camera_size": 24}
    with pytest.raises(ConfigError, match=r"config.env.camera_yaml \S*pepper.yaml: a 58.0 deg camera"):
        load_config(None, cfg | {"env": {"camera_yaml": pepper_like}})


def test_config_checks_the_encoder_checkpoint(checkpoints: dict[str, Path]) -> None:
    saev = str(checkpoints["saev"])
    ok = load_config(None, {"obs_mode": "camera_speed", "encoder": "saev", "encoder_checkpoint": saev,
                            "camera_size": 24})
    assert ok.encoder_file == saev and ok.policy_obs_mode == "vector"
    with pytest.raises(ConfigError, match="camera_size = 84: expected 24, the input resolution"):
        load_config(None, {"obs_mode": "camera", "encoder": "saev", "encoder_checkpoint": saev})
    with pytest.raises(ConfigError, match="a conv checkpoint .* it holds a saev autoencoder"):
        load_config(None, {"obs_mode": "camera", "encoder": "conv", "encoder_checkpoint": saev, "camera_size": 24})
    with pytest.raises(ConfigError, match="encoder_checkpoint = 'nosuch.pt'"):
        load_config(None, {"obs_mode": "camera", "encoder": "conv", "encoder_checkpoint": "nosuch.pt"})
    with pytest.raises(UserError, match="takes 24x24 images, the camera renders 32x32"):
        make_env(obs_mode="camera", camera_width=32, camera_height=32, encoder=saev)
    with pytest.raises(UserError, match="needs camera observations"):
        make_env(obs_mode="vector", camera_width=24, camera_height=24, encoder=saev)


@pytest.mark.slow
@pytest.mark.parametrize("obs_mode,policy,smoothing", [("camera_speed", "lstm", 1.0), ("camera", "ff", 0.5)])
def test_train_and_evaluate_a_camera_policy(checkpoints: dict[str, Path], tmp_path: Path, obs_mode: str,
                                            policy: str, smoothing: float) -> None:
    from ssbl_pb.agents.trained import policy_env_kwargs
    from ssbl_pb.analysis.evaluation import Setup, evaluate
    from ssbl_pb.training.run import train

    cfg = load_config(None, {"obs_mode": obs_mode, "encoder": "saev", "policy": policy, "camera_size": 24,
                             "feature_smoothing": smoothing,
                             "encoder_checkpoint": str(checkpoints["saev"]), "n_envs": 2, "total_steps": 64,
                             "eval_every": 32, "eval_episodes": 1, "baseline_episodes": 1, "checkpoint_every": 64,
                             "env": {"task": {"max_steps": 20}}, "ppo": {"n_steps": 16, "batch_size": 16}})
    summary = train(cfg, tmp_path / "run")
    assert summary["steps"] == 64 and summary["best_eval"] is not None
    # the features' low-pass travels with the model to every env it is evaluated in
    assert policy_env_kwargs(str(tmp_path / "run")).get("feature_smoothing", 1.0) == smoothing
    summary, results = evaluate(Setup(str(tmp_path / "run"), env_kwargs=(("task", {"max_steps": 20}),)), 2, 5,
                                tmp_path / "eval")
    assert len(results) == 2 and summary["policy"] == str(tmp_path / "run")
    assert (tmp_path / "eval" / "summary.json").is_file()


def test_shipped_camera_speed_saev_policy_runs_with_its_encoder() -> None:
    from ssbl_pb.analysis.evaluation import Setup

    env, policy = Setup("camera_speed_saev")()  # no --obs-mode: the policy brings its camera mode and encoder
    obs, _ = env.reset(seed=500_000)
    assert obs.shape == (3 * 16 + 2,) and env.unwrapped is not env
    state, start = None, np.ones(1, bool)
    for _ in range(3):
        action, state = policy.predict(obs, state=state, episode_start=start)
        start = np.zeros(1, bool)
        assert action.shape == (2,) and np.all(np.abs(action) <= 1)
        obs, *_ = env.step(action)
    env.close()


def test_low_pass_episodes_restarts_at_each_episode() -> None:
    from ssbl_pb.env.gymenv.encoded import low_pass_episodes

    x = np.array([[0.0], [4.0], [8.0], [2.0], [6.0]], np.float32)
    got = low_pass_episodes(x, np.array([0, 0, 0, 1, 1]), 0.5)
    # episode 0: 0, 0 + 0.5 (4 - 0) = 2, 2 + 0.5 (8 - 2) = 5; episode 1 starts again: 2, 2 + 0.5 (6 - 2) = 4
    assert np.allclose(got[:, 0], [0.0, 2.0, 5.0, 2.0, 4.0])
    assert np.array_equal(low_pass_episodes(x, np.zeros(5), 1.0), x)


def test_feature_jitter_by_hand_and_falls_with_the_low_pass(checkpoints: dict[str, Path]) -> None:
    from ssbl_pb.bench.camera import feature_jitter
    from tests.test_ae_training import moving_square

    data = moving_square(10, 12)
    res = feature_jitter(data, {k: str(v) for k, v in checkpoints.items()}, alphas=(1.0, 0.5, 0.2))
    enc = load_encoder(checkpoints["saev"])
    f = enc.encode(data["frames"])
    f = f / (f.std(axis=0) + 1e-6)
    same = data["episode"][1:] == data["episode"][:-1]
    assert res["saev/alpha=1"]["first_difference"] == pytest.approx(np.abs(np.diff(f, axis=0))[same].mean(),
                                                                     abs=1e-4)
    for arch in A.ARCHS:
        second = [res[f"{arch}/alpha={a:g}"]["second_difference"] for a in (1.0, 0.5, 0.2)]
        assert second[0] > second[1] > second[2] > 0, second
