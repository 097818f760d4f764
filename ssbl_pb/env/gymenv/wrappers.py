"""Observation modes as wrappers of the one core env (paper III-B: Vector, CameraOnly, CameraSpeed), and the
agent-side action stages used in training (smoothing, safety shield)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from ...core import observation as ob
from ...core.shield import SafetyShield, ShieldParams
from ...errors import UserError

OBS_MODES = ("vector", "camera", "camera_speed")


class CameraObservation(gym.ObservationWrapper):
    """Pepper's first-person RGB image (H, W, 3) uint8 instead of the vector (CameraOnly mode)."""

    def __init__(self, env: gym.Env, width: int = 84, height: int = 84, projection: list[float] | None = None):
        super().__init__(env)
        if not (isinstance(width, int) and isinstance(height, int) and 8 <= width <= 1024 and 8 <= height <= 1024):
            raise UserError(f"camera size {width}x{height}: expected integers in [8, 1024]")
        self.width, self.height, self.projection = width, height, projection
        self.observation_space = gym.spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8)

    def image(self) -> np.ndarray:
        rgb, _ = self.env.unwrapped.world.render_first_person(self.width, self.height, self.projection)
        return rgb

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return self.image()


class CameraSpeedObservation(CameraObservation):
    """Image plus the robot's own velocity (forward, left, turn; normalised), a Dict (CameraSpeed mode)."""

    def __init__(self, env: gym.Env, width: int = 84, height: int = 84, projection: list[float] | None = None):
        super().__init__(env, width, height, projection)
        self.observation_space = gym.spaces.Dict({
            "image": gym.spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8),
            "speed": gym.spaces.Box(-1.5, 1.5, shape=(3,), dtype=np.float32),
        })

    def observation(self, observation: np.ndarray) -> dict[str, np.ndarray]:
        # the Vector layout's normalised body velocity and turn rate (core.observation)
        speed = observation[ob.VEL_FORWARD:ob.TURN_RATE + 1]
        return {"image": self.image(), "speed": np.clip(speed, -1.5, 1.5).astype(np.float32)}


class ExponentialFilter:
    """``y_t = y_{t-1} + alpha (x_t - y_{t-1})`` per row of a batch (or of one vector), started at the first
    input; ``alpha = 1`` passes the input through. The stateful filter behind the action smoothing and the
    encoded features' low-pass (``env.gymenv.encoded``)."""

    def __init__(self, alpha: float) -> None:
        self.alpha = float(alpha)
        self.state: np.ndarray | None = None
        self._fresh: np.ndarray | None = None  # rows (of a batch) whose episode has just begun

    def reset(self, rows: list[int] | None = None) -> None:
        """Forget the past inputs (of the given rows of a batch only, when ``rows`` is given)."""
        if rows is None or self.state is None:
            self.state, self._fresh = None, None
            return
        if self._fresh is None:
            self._fresh = np.zeros(len(self.state), dtype=bool)
        self._fresh[rows] = True

    def peek(self, x: np.ndarray) -> np.ndarray:
        """The output for input ``x`` without advancing the state (rows flagged fresh pass ``x`` through)."""
        x = np.asarray(x, dtype=np.float32)
        if self.state is None:
            return x
        new = (self.state + self.alpha * (x - self.state)).astype(np.float32)
        return new if self._fresh is None else np.where(self._fresh[:, None], x, new)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.state = self.peek(x)
        self._fresh = None
        return self.state


class ActionFilter(ExponentialFilter):
    """The action smoothing's filter (``ActionStages``; one row per copy in the batched training env): actions
    clipped to [-1, 1], then filtered."""

    def __call__(self, action: np.ndarray) -> np.ndarray:
        return super().__call__(np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0))


def wrap_obs_mode(env: gym.Env, obs_mode: str, width: int = 84, height: int = 84,
                  projection: list[float] | None = None) -> gym.Env:
    """The env seen through ``obs_mode`` (``projection``: a calibrated camera's, else Pepper's FOV)."""
    if obs_mode == "vector":
        return env
    if obs_mode == "camera":
        return CameraObservation(env, width, height, projection)
    if obs_mode == "camera_speed":
        return CameraSpeedObservation(env, width, height, projection)
    raise UserError(f"obs_mode {obs_mode!r}: expected one of {OBS_MODES}")


class ActionStages:
    """The agent's action stages in their one order, built here for training (``training.vec_env``,
    ``training.run.EnvFactory``), evaluation and deploy (``trained.TrainedPolicy``): the action clipped and smoothed
    (``ActionFilter`` with ``smoothing``, ``u_t = u_{t-1} + alpha (a_t - u_{t-1})``; 1: off), then the safety shield
    (``shield``: its ``ShieldParams``, None: off) on the Vector observation the action answers, so the shield acts
    last. One action or a batch of rows (one per copy). Part of the learned agent, not of the robot (the paper: "a
    smoothing algorithm can also be applied to the learned policy"): the closed loop is the same in training,
    evaluation and deploy."""

    def __init__(self, smoothing: float = 1.0, shield: ShieldParams | None = None) -> None:
        if not 0.0 < smoothing <= 1.0:
            raise UserError(f"action smoothing alpha {smoothing!r}: expected a number in (0, 1]")
        self.filter = ActionFilter(smoothing) if smoothing < 1.0 else None
        self.shield = SafetyShield(shield) if shield is not None else None

    def reset(self, rows: list[int] | None = None) -> None:
        """A new episode (of the given rows of a batch only): the filter forgets the past actions."""
        if self.filter is not None:
            self.filter.reset(rows)

    def __call__(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        a = action if self.filter is None else self.filter(action)
        return a if self.shield is None else self.shield(obs, a)


class ActionStagesWrapper(gym.Wrapper):
    """``ActionStages`` around a Vector-mode env (it keeps the observation each action answers); each step's
    ``info["shield"]`` says what the shield changed (``ShieldRecord.row``), None if nothing or no shield."""

    def __init__(self, env: gym.Env, stages: ActionStages) -> None:
        super().__init__(env)
        self.stages = stages
        self._obs: np.ndarray | None = None

    def reset(self, **kwargs):  # type: ignore[override]
        self.stages.reset()
        obs, info = self.env.reset(**kwargs)
        self._obs = obs
        return obs, info

    def step(self, action: np.ndarray):  # type: ignore[override]
        if self._obs is None:
            raise RuntimeError("ActionStagesWrapper.step called before reset")
        obs, r, terminated, truncated, info = self.env.step(self.stages(self._obs, action))
        self._obs = obs
        shield = self.stages.shield
        return obs, r, terminated, truncated, {**info, "shield": None if shield is None else shield.last.row()}


class ShieldWrapper(ActionStagesWrapper):
    """The safety shield alone around a Vector-mode env (``params``: default, the env's robot at Pepper's limits)."""

    def __init__(self, env: gym.Env, params: ShieldParams | None = None) -> None:
        core = env.unwrapped
        super().__init__(env, ActionStages(1.0, params or ShieldParams.from_env(core.robot_params, core.social,
                                                                                core.task)))
        self.shield = self.stages.shield
        self.params = self.shield.params
