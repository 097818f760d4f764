"""Observation modes as wrappers of the one core env (paper III-B: Vector, CameraOnly, CameraSpeed), and the
agent-side action stages used in training (smoothing, safety shield)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from ..errors import UserError
from . import observation as ob
from .shield import SafetyShield, ShieldParams

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
        # the Vector layout's normalised body velocity and turn rate (env.observation)
        speed = observation[ob.VEL_FORWARD:ob.TURN_RATE + 1]
        return {"image": self.image(), "speed": np.clip(speed, -1.5, 1.5).astype(np.float32)}


class ActionSmoothing(gym.ActionWrapper):
    """Exponential smoothing of the agent's actions, ``u_t = u_{t-1} + alpha (a_t - u_{t-1})``.

    Part of the learned agent, not of the robot (the paper: "a smoothing algorithm can also be applied to the
    learned policy"): training wraps the env with it and ``TrainedPolicy`` applies the same filter when it acts,
    so the closed loop is the same in training, evaluation and deploy. ``alpha = 1`` is no smoothing.
    """

    def __init__(self, env: gym.Env, alpha: float) -> None:
        super().__init__(env)
        if not 0.0 < alpha <= 1.0:
            raise UserError(f"action smoothing alpha {alpha!r}: expected a number in (0, 1]")
        self.filter = ActionFilter(alpha)

    def reset(self, **kwargs):  # type: ignore[override]
        self.filter.reset()
        return self.env.reset(**kwargs)

    def action(self, action: np.ndarray) -> np.ndarray:
        return self.filter(action)


class ShieldWrapper(gym.Wrapper):
    """Applies the safety shield (``env.shield``) to every action, from the latest Vector observation; each
    step's ``info["shield"]`` says what it changed (``ShieldRecord.row``: before, after, rules), None if nothing.

    Wraps the Vector-mode env directly (the agent's smoothing goes outside it, so the shield acts last)."""

    def __init__(self, env: gym.Env, params: ShieldParams | None = None) -> None:
        super().__init__(env)
        core = env.unwrapped
        self.shield = SafetyShield(params or ShieldParams.from_env(core.robot_params, core.social, core.task))
        self.params = self.shield.params
        self._obs: np.ndarray | None = None

    def reset(self, **kwargs):  # type: ignore[override]
        obs, info = self.env.reset(**kwargs)
        self._obs = obs
        return obs, info

    def step(self, action: np.ndarray):  # type: ignore[override]
        if self._obs is None:
            raise RuntimeError("ShieldWrapper.step called before reset")
        obs, r, terminated, truncated, info = self.env.step(self.shield(self._obs, action))
        self._obs = obs
        return obs, r, terminated, truncated, {**info, "shield": self.shield.last.row()}


class ExponentialFilter:
    """``y_t = y_{t-1} + alpha (x_t - y_{t-1})`` per row of a batch (or of one vector), started at the first
    input; ``alpha = 1`` passes the input through. The stateful filter behind the action smoothing and the
    encoded features' low-pass (``env.encoded``)."""

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
    """The action smoothing's filter (``ActionSmoothing``; also used by trained policies at inference and, one
    row per copy, by the batched training env): actions clipped to [-1, 1], then filtered."""

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
