"""The batched training env plays the same episodes as the single env (``env.engine.batched``, ``training.vec_env``)."""


import numpy as np
import pytest

from ssbl_pb.agents.policies import SFFMPolicy, StraightPolicy
from ssbl_pb.core import observation as ob
from ssbl_pb.core.actions import ActionFilter
from ssbl_pb.core.reward import TERMS, RewardWeights, total_reward, weight_vector
from ssbl_pb.core.shield import ShieldParams, shield_action, shield_actions
from ssbl_pb.env.engine.batched import BatchedApproach
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv


def _drive(num: int, steps: int, seed: int, noise: float = 0.15, **kwargs):
    """Step N single envs and one batch of N with the same actions (the SFFM baseline on even copies, straight to
    the slot on odd ones, plus noise, so episodes end in successes, intrusions and time-outs); yields (single
    results, batch results) per step."""
    singles = [ApproachGroupEnv(**kwargs) for _ in range(num)]
    batch = BatchedApproach(num, **kwargs)
    for i, env in enumerate(singles):
        env.reset(seed=seed + i)
        batch.seed(i, seed + i)
        batch.reset(i)
    policies, rng = [SFFMPolicy(), StraightPolicy()], np.random.default_rng(seed)
    try:
        for _ in range(steps):
            obs = batch.observations()
            act = np.stack([policies[i % 2].act(o) for i, o in enumerate(obs)])
            act = np.clip(act + rng.normal(0, noise, (num, 2)), -1, 1)
            act = np.concatenate([act, rng.uniform(-1, 1, (num, batch.n_act - 2))], axis=1).astype(np.float32)
            single = [env.step(a) for env, a in zip(singles, act, strict=True)]
            result = batch.step(act)
            yield singles, single, batch, result
            for i, (_, _, term, trunc, _) in enumerate(single):
                if term or trunc:
                    singles[i].reset()
                    batch.reset(i)
    finally:
        for env in singles:
            env.close()


@pytest.mark.parametrize("kwargs", [
    {"scenario": "mixed"},
    {"scenario": "default,circular-5", "robot": {"latency_s": 0.15, "time_constant_s": 0.2}},
    {"scenario": "l_shape", "task": {"turn": True}},
    {"scenario": "mixed", "groups": "paper"},
    {"scenario": "mixed@furnished,default@furnished"},
], ids=["mixed", "calibrated-base", "policy-turns", "paper-groups", "furnished-rooms"])
def test_batch_matches_single_env(kwargs):
    endings = {"success": 0, "violation": 0, "truncated": 0}
    for singles, single, batch, (rew, term, trunc) in _drive(6, 600, 7, **kwargs):
        for i, (obs, r, te, tr, info) in enumerate(single):
            assert np.allclose(batch.observations()[i], obs, atol=1e-5)  # terminal observations too
            assert r == pytest.approx(rew[i], abs=1e-9)
            assert (te, tr) == (bool(term[i]), bool(trunc[i]))
            assert info["success"] == batch.success[i] and info["violation"] == batch.violation[i]
            assert np.allclose(batch.pose[i], singles[i].world.robot_pose, atol=1e-9)
            n = singles[i].world.group.n
            assert np.allclose(batch.pos[i, :n], singles[i].world.group.pos, atol=1e-9)
            if te or tr:
                got = batch.episode_terms(i)
                for k, v in info["episode_terms"].items():
                    assert got[k] == pytest.approx(v, abs=1e-7), k
                endings["success" if info["success"] else "violation" if te else "truncated"] += 1
    assert endings["success"] >= 2 and endings["violation"] >= 1, endings  # the comparison saw real endings


def test_batch_free_slot_and_observation_after_reset():
    batch = BatchedApproach(3, scenario="circular")
    for i in range(3):
        batch.seed(i, 40 + i)
        info = batch.reset(i)
        env = ApproachGroupEnv(scenario="circular")
        obs, single_info = env.reset(seed=40 + i)
        assert info == single_info
        assert np.array_equal(batch.slot[i], env.slot())
        assert np.allclose(batch.observations()[i], obs, atol=1e-6)
        assert batch.observations()[i, 14 + 5 * info["n_humans"]:39].sum() == 0.0  # absent members are zeros
        env.close()


def test_batch_rejects_bad_arguments():
    with pytest.raises(ValueError, match="number of copies"):
        BatchedApproach(0)
    with pytest.raises(ValueError, match="scenario 'nope'"):
        BatchedApproach(2, scenario="nope")
    with pytest.raises(ValueError, match="w_smooth"):
        BatchedApproach(2).set_reward_weights(w_smooth=-1.0)


def test_weight_vector_is_eq15():
    rng = np.random.default_rng(4)
    w = RewardWeights(w1=0.3, w_e=0.5, w_a=0.7, w_rep=2.0, violation_penalty=4.0)
    for _ in range(5):
        terms = dict(zip(TERMS, rng.normal(size=len(TERMS)), strict=True))
        assert np.array([terms[k] for k in TERMS]) @ weight_vector(w) == pytest.approx(total_reward(terms, w),
                                                                                       abs=1e-12)


def _random_obs(rng: np.random.Generator, n: int) -> np.ndarray:
    obs = np.zeros((n, ob.OBS_SIZE), dtype=np.float32)
    for row in obs:
        k = int(rng.integers(0, 6))
        block = row[14:39].reshape(5, 5)
        block[:k, 0:2] = rng.uniform(-0.3, 0.3, (k, 2))  # members within 1.5 m (x POS_SCALE)
        block[:k, 2:4] = rng.normal(0, 0.4, (k, 2))
        block[:k, 4] = 1.0
        row[39] = rng.uniform(-1, 1)
        row[ob.BASE_SIZE:] = np.where(rng.uniform(size=ob.SCAN_RAYS) < 0.2, rng.uniform(0.05, 0.5, ob.SCAN_RAYS), 1.0)
    return obs


def test_shield_actions_match_single_shield():
    rng = np.random.default_rng(5)
    obs = _random_obs(rng, 300)
    act = rng.uniform(-1.3, 1.3, (300, 2)).astype(np.float32)  # beyond the box: the speed cap applies too
    p = ShieldParams()
    got = shield_actions(obs, act, p)
    want = np.stack([shield_action(o, a, p) for o, a in zip(obs, act, strict=True)])
    assert got.dtype == np.float32 and np.allclose(got, want, atol=1e-6)
    assert (np.abs(got - np.clip(act, -1, 1)) > 1e-3).any(axis=1).sum() > 30  # it did cut some


def test_action_filter_resets_single_rows():
    f = ActionFilter(0.5)
    f(np.zeros((3, 2)))
    out = f(np.ones((3, 2)))
    assert np.allclose(out, 0.5)
    f.reset(rows=[1])
    out = f(np.ones((3, 2)))
    assert np.allclose(out[:, 0], [0.75, 1.0, 0.75])  # row 1 starts again from its first action
    f.reset()
    assert np.allclose(f(np.full((3, 2), 0.2)), 0.2)
