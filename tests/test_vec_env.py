"""``BatchedVecEnv`` behaves as SB3's DummyVecEnv over our single envs, action stages included."""

import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from ssbl_pb.agents.policies import SFFMPolicy
from ssbl_pb.params import ConfigError
from ssbl_pb.training.config import TrainConfig
from ssbl_pb.training.run import EnvFactory, make_vec_env
from ssbl_pb.training.vec_env import BatchedVecEnv


def test_batched_vec_env_matches_dummy_vec_env():
    kwargs = {"scenario": "mixed", "reward": {"w_prox": 2.0}}
    ref = DummyVecEnv([EnvFactory({"obs_mode": "vector", **kwargs}, monitor=False, smoothing=0.4, shield=True)] * 4)
    venv = BatchedVecEnv(4, smoothing=0.4, shield=True, **kwargs)
    for v in (ref, venv):
        v.seed(11)
    obs_ref, obs = ref.reset(), venv.reset()
    assert np.allclose(obs, obs_ref, atol=1e-6)
    policy, rng = SFFMPolicy(), np.random.default_rng(0)
    ended = successes = 0
    for _ in range(900):
        act = np.clip(np.stack([policy.act(o) for o in obs]) + rng.normal(0, 0.15, (4, 2)), -1, 1).astype(np.float32)
        obs_ref, r_ref, d_ref, i_ref = ref.step(act)
        obs, r, d, info = venv.step(act)
        assert np.allclose(obs, obs_ref, atol=1e-5)
        assert np.allclose(r, r_ref, atol=1e-6) and np.array_equal(d, d_ref)
        for a, b in zip(info, i_ref, strict=True):
            if "terminal_observation" in b:
                ended += 1
                successes += b["is_success"]
                assert a["is_success"] == b["is_success"]
                assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
                assert np.allclose(a["terminal_observation"], b["terminal_observation"], atol=1e-5)
                assert a["episode_terms"]["reward"] == pytest.approx(b["episode_terms"]["reward"], abs=1e-5)
    assert ended >= 8 and successes >= 1  # resets and their seeding were compared too


def test_batched_vec_env_attribute_access():
    venv = BatchedVecEnv(3)
    assert venv.get_attr("render_mode") == [None, None, None]
    venv.env_method("set_reward_weights", w_smooth=0.25)
    assert venv.get_attr("weights")[0].w_smooth == 0.25
    with pytest.raises(ValueError, match="address all of them"):
        venv.env_method("set_reward_weights", indices=[0], w_smooth=0.3)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        venv.get_attr("nope")
    with pytest.raises(ValueError, match="smoothing alpha"):
        BatchedVecEnv(2, smoothing=0.0)


def test_config_chooses_the_vec_env():
    assert TrainConfig().vec_env_kind == "batched"
    assert TrainConfig(obs_mode="camera", encoder="cnn").vec_env_kind == "dummy"
    assert TrainConfig(vec_env="dummy").vec_env_kind == "dummy"
    with pytest.raises(ConfigError, match="vec_env.*batched steps the Vector mode only"):
        TrainConfig(obs_mode="camera", encoder="cnn", vec_env="batched")
    with pytest.raises(ConfigError, match="vec_env"):
        TrainConfig(vec_env="threads")


def test_make_vec_env_batched_reports_episodes():
    cfg = TrainConfig(n_envs=2, env={"task": {"max_steps": 5}})
    venv = make_vec_env(cfg, 3)
    venv.reset()
    infos = []
    for _ in range(5):
        _, _, done, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
    assert done.all()
    assert all(info["episode"]["l"] == 5 and info["is_success"] is False for info in infos)  # VecMonitor's record
    venv.close()


def test_batched_evaluation_matches_single_env_episodes():
    from ssbl_pb.agents.rollout import run_episode
    from ssbl_pb.agents.trained import load_trained, shield_at_place
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.training.vec_env import evaluate_first_episodes

    single = load_trained("vector", shield=True)  # the shipped policy: smoothing 0.4 and the shield
    env = make_env(scenario="mixed")
    want = [run_episode(env, single, 900 + i, keep_trajectory=False).metrics for i in range(6)]
    env.close()
    venv = BatchedVecEnv(6, smoothing=single.filter.alpha, shield=True, shield_at_place=shield_at_place("vector"),
                         scenario="mixed")
    venv.seed(900)
    success, returns = evaluate_first_episodes(single.model, single.normalizer, False, venv)
    assert success.tolist() == [bool(m["success"]) for m in want]
    # the network's batch of 6 and its single rows differ in the last float32 bits; where the shield clips, that
    # difference grows over an episode (measured: 0.01 of return in one of the six, from step 107)
    assert np.allclose(returns, [m["return"] for m in want], atol=0.05)
    assert 2 <= success.sum() < 6  # both endings were compared (the shipped policy: 3 of these 6 mixed starts)


def test_dummy_and_batched_training_envs_start_alike():
    obs = {}
    for kind in ("dummy", "batched"):
        venv = make_vec_env(TrainConfig(n_envs=3, vec_env=kind, scenario="mixed"), 5)
        obs[kind] = venv.venv.reset()
        assert type(venv.venv).__name__ == ("DummyVecEnv" if kind == "dummy" else "VecMonitor")
        venv.close()
    assert np.allclose(obs["dummy"], obs["batched"], atol=1e-6)


def test_batched_evaluation_of_a_recurrent_policy_matches_single_env():
    from sb3_contrib import RecurrentPPO

    from ssbl_pb.agents.rollout import run_episode
    from ssbl_pb.agents.trained import TrainedPolicy
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.training.policies import bounded_policy
    from ssbl_pb.training.vec_env import evaluate_first_episodes

    kwargs = {"scenario": "mixed", "task": {"max_steps": 40}}
    venv = BatchedVecEnv(3, smoothing=0.4, shield=True, **kwargs)
    model = RecurrentPPO(bounded_policy("vector", True), venv, n_steps=16, batch_size=16, seed=3, device="cpu",
                         policy_kwargs={"lstm_hidden_size": 16, "net_arch": [16]})
    single = TrainedPolicy(model, None, recurrent=True, smoothing=0.4, shield=True)
    env = make_env(**kwargs)
    want = [run_episode(env, single, 70 + i, keep_trajectory=False).metrics for i in range(3)]
    env.close()
    venv.seed(70)
    success, returns = evaluate_first_episodes(model, None, True, venv)
    assert np.allclose(returns, [m["return"] for m in want], atol=1e-4)
    assert success.tolist() == [bool(m["success"]) for m in want]


def test_bench_training_rejects_unknown_config_keys(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "bench.json"
    res = subprocess.run([sys.executable, str(root / "tools" / "bench_training.py"), "--set", "n_envz=3", "--out",
                          str(out)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "n_envz" in res.stderr and not out.exists()


def test_set_attr_weights_changes_the_rewards_at_once():
    act = np.full((3, 2), 0.5, dtype=np.float32)
    changed = BatchedVecEnv(3, scenario="mixed")
    fresh = BatchedVecEnv(3, scenario="mixed", reward={"w3": 40.0, "w_prox": 3.0})
    for v in (changed, fresh):
        v.seed(5)
        v.reset()
    changed.set_attr("weights", {"w3": 40.0, "w_prox": 3.0})
    assert changed.get_attr("weights")[0].w3 == 40.0
    r_changed, r_fresh = changed.step(act)[1], fresh.step(act)[1]
    assert np.allclose(r_changed, r_fresh)
    default = BatchedVecEnv(3, scenario="mixed")
    default.seed(5)
    default.reset()
    assert not np.allclose(default.step(act)[1], r_changed)  # the new weights made a difference


def test_reset_options_pick_the_group_in_single_and_batched_envs():
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.errors import UserError

    env = make_env(scenario="default")
    _, info = env.reset(seed=3, options={"n_humans": 4, "formation": "circular"})
    assert (info["n_humans"], info["formation"]) == (4, "circular") and len(env.unwrapped.world.group.pos) == 4
    with pytest.raises(UserError, match="reset options \\['size'\\]"):
        env.reset(seed=3, options={"size": 4})
    venv = BatchedVecEnv(2, scenario="default")
    venv.seed(3)
    venv.set_options({"n_humans": 4, "formation": "circular"})
    obs = venv.reset()
    assert [i["n_humans"] for i in venv.reset_infos] == [4, 4]
    single_obs, _ = env.reset(seed=3, options={"n_humans": 4, "formation": "circular"})
    assert np.allclose(obs[0], single_obs, atol=1e-6)  # the same episode as the single env with those options
    venv.reset()
    assert [i["n_humans"] for i in venv.reset_infos] == [2, 2]  # options apply to the next reset only


def test_the_shield_penalty_costs_each_step_how_far_the_shield_moved_the_action_in_both_vec_envs():
    from ssbl_pb.core.shield import ShieldRecord

    before = np.array([[0.6, 0.8], [1.2, 1.6], [2.0, 0.0]])
    rec = ShieldRecord(before, np.array([[0.0, 0.8], [0.3, 0.4], [2.0, 0.0]]), np.array([1, 1, 0]))
    # braked to a stop ahead: 0.6; capped at 1 (0.6, 0.8), then halved: 0.5, not the cap's 1.5; untouched: 0
    assert rec.correction() == pytest.approx([0.6, 0.5, 0.0])
    kwargs = {"scenario": "mixed"}
    plain, paid = (BatchedVecEnv(4, 0.4, True, False, w, **kwargs) for w in (0.0, 0.5))
    single = DummyVecEnv([EnvFactory({"obs_mode": "vector", **kwargs}, monitor=False, smoothing=0.4, shield=True,
                                     shield_penalty=0.5)] * 4)
    for v in (plain, paid, single):
        v.seed(3)
        v.reset()
    shielded = 0.0
    for _ in range(60):  # full speed ahead: into the group, where the shield brakes
        act = np.tile(np.array([1.0, 0.3], dtype=np.float32), (4, 1))
        _, r0, d0, _ = plain.step(act)
        _, r1, d1, _ = paid.step(act)
        _, r2, _, _ = single.step(act)
        moved = paid.stages.shield.last.correction()
        assert np.allclose(r1, r0 - 0.5 * moved, atol=1e-6) and np.allclose(r2, r1, atol=1e-5)
        assert np.array_equal(d0, d1)  # the same steps: the penalty changes the reward only
        shielded += float(moved.sum())
    assert shielded > 1.0  # the shield did move those actions
    plain, paid = (BatchedVecEnv(2, 0.4, True, False, w, scenario="mixed") for w in (0.0, 0.5))
    for v in (plain, paid):
        v.seed(3)
        v.reset()
    paid.batch.driven[:] = [False, True]  # as the observation model marks a step its search or a look took over
    taken = 0.0
    for _ in range(60):
        act = np.tile(np.array([1.0, 0.3], dtype=np.float32), (2, 1))
        r0, r1 = plain.step(act)[1], paid.step(act)[1]
        moved = paid.stages.shield.last.correction()
        assert r1[0] == pytest.approx(r0[0], abs=1e-6) and r1[1] == pytest.approx(r0[1] - 0.5 * moved[1], abs=1e-6)
        taken += float(moved[0])
    assert taken > 0.0  # the shield moved the first copy's actions: their cost was left out
    with pytest.raises(ConfigError, match="shield_penalty"):
        TrainConfig(safety_shield=False, shield_penalty=0.1)
