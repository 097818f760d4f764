"""``BatchedVecEnv``: SB3's VecEnv interface over ``env.engine.batched.BatchedApproach`` (Vector observation).

It does what ``DummyVecEnv`` over N ``EnvFactory`` envs does, action stages included (the agent's smoothing,
then the safety shield), with one compiled step for all copies instead of N Python steps. Seeding follows SB3:
``seed(s)`` gives copy i the seed ``s + i`` at the next ``reset()``, later episodes continue its generator,
as a single env's do. Wrap it in SB3's ``VecMonitor`` (episode returns and lengths, ``is_success``) and
``VecNormalize`` as usual (``training.run.make_vec_env`` does).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from ..agents.trained import TrainedPolicy
from ..core import observation as ob
from ..core.actions import ActionStages
from ..env.engine.batched import BatchedApproach


class BatchedVecEnv(VecEnv):
    """``num`` copies of the Vector-mode task; ``env_kwargs`` as for ``BatchedApproach`` (scenario, weights...)."""

    def __init__(self, num: int, smoothing: float = 1.0, shield: bool = False, shield_at_place: bool = False,
                 shield_penalty: float = 0.0, **env_kwargs: Any) -> None:
        self.batch = BatchedApproach(num, **env_kwargs)
        b = self.batch
        self.stages = ActionStages.of(b, smoothing, shield, shield_at_place)
        self.shield_penalty = shield_penalty  # reward per unit the shield moves an action (TrainConfig's)
        self.render_mode = None
        size = b.obs_size  # with the range scan or without (``scan=False``)
        obs_space = gym.spaces.Box(-ob.OBS_LIMIT, ob.OBS_LIMIT, shape=(size,), dtype=np.float32)
        act_space = gym.spaces.Box(-1.0, 1.0, shape=(b.n_act,), dtype=np.float32)
        super().__init__(num, obs_space, act_space)
        self._obs = np.zeros((num, size), dtype=np.float32)
        self._actions = np.zeros((num, b.n_act), dtype=np.float32)

    def _start(self, i: int) -> dict[str, Any]:
        if self._seeds[i] is not None:
            self.batch.seed(i, self._seeds[i])
        info = self.batch.reset(i, self._options[i])
        self.stages.reset(rows=[i])
        return info

    def reset(self) -> np.ndarray:
        self.reset_infos = [self._start(i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        self._obs = self.batch.observations()
        return self._obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        b = self.batch
        rewards, terminated, truncated = b.step(self.stages(self._obs, self._actions))
        if self.shield_penalty > 0 and self.stages.shield is not None:  # on the actions executed (``driven``)
            rewards = rewards - self.shield_penalty * self.stages.shield.last.correction() * b.driven
        obs = b.observations()
        done = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(done).tolist():
            infos[i] = {"is_success": bool(b.success[i]), "episode_terms": b.episode_terms(i),
                        "terminal_observation": obs[i].copy(), "TimeLimit.truncated": bool(truncated[i])}
            self.reset_infos[i] = self._start(i)
        if done.any():
            obs = b.observations(np.flatnonzero(done))
        self._obs = obs
        return obs.copy(), rewards.astype(np.float32), done, infos

    def close(self) -> None:
        pass

    # -- attribute access (SB3 callbacks reach envs through these) ----------------------------------------
    def _target(self, attr: str) -> Any:
        for obj in (self.batch, self):
            if hasattr(obj, attr):
                return obj
        raise AttributeError(f"BatchedVecEnv has no attribute {attr!r}")

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self._target(attr_name), attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._all(indices, f"set_attr({attr_name!r})")
        setattr(self._target(attr_name), attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        self._all(indices, f"env_method({method_name!r})")
        out = getattr(self.batch, method_name)(*method_args, **method_kwargs)  # shared by every copy
        return [out for _ in range(self.num_envs)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> Sequence[bool]:
        return [False for _ in self._get_indices(indices)]

    def _all(self, indices: VecEnvIndices, what: str) -> None:
        if sorted(self._get_indices(indices)) != list(range(self.num_envs)):
            raise ValueError(f"BatchedVecEnv.{what}: the copies share their parameters; address all of them")


def evaluate_first_episodes(model: Any, normalizer: Any, recurrent: bool, venv: BatchedVecEnv
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Success (N,) and return (N,) of each copy's first episode under ``model`` acting deterministically on
    observations normalised by ``normalizer`` (a ``VecNormalize``; None: raw). Seed ``venv`` first: copy i then
    plays the episode a single env reset with seed ``s + i`` plays, as ``rollout.run_episode`` would run it with
    the same model (the agent's smoothing and shield act inside ``venv``)."""
    policy = TrainedPolicy(model, normalizer, recurrent)
    n = venv.num_envs
    obs = venv.reset()
    active, success, returns = np.ones(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n)
    state, start = None, np.ones(n, dtype=bool)
    while active.any():
        action, state = policy.predict(obs, state, start, deterministic=True)
        obs, rewards, done, infos = venv.step(action)
        returns += np.where(active, rewards, 0.0)
        for i in np.flatnonzero(done & active).tolist():
            success[i] = infos[i]["is_success"]
        active &= ~done
        start = done
    return success, returns
