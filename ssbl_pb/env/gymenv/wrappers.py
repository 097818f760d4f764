"""Observation modes as wrappers of the one core env (paper III-B: Vector, CameraOnly, CameraSpeed), and the
agent's action stages (``core.actions``) around a Vector-mode env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from ...core import observation as ob
from ...core.actions import ActionStages
from ...core.shield import ShieldParams
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


class ActionStagesWrapper(gym.Wrapper):
    """``ActionStages`` around a Vector-mode env (it keeps the observation each action answers); each step's
    ``info["shield"]`` says what the shield changed (``ShieldRecord.row``), None if nothing or no shield."""

    def __init__(self, env: gym.Env, stages: ActionStages, shield_penalty: float = 0.0) -> None:
        super().__init__(env)
        self.stages = stages
        self.shield_penalty = shield_penalty  # reward per unit the shield moves the action (TrainConfig's)
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
        if self.shield_penalty > 0 and shield is not None and self.env.unwrapped.sim.driven[0]:  # executed
            r = float(r) - self.shield_penalty * float(shield.last.correction()[0])
        return obs, r, terminated, truncated, {**info, "shield": None if shield is None else shield.last.row()}


class ShieldWrapper(ActionStagesWrapper):
    """The safety shield alone around a Vector-mode env (``params``: default, the env's robot at Pepper's limits)."""

    def __init__(self, env: gym.Env, params: ShieldParams | None = None) -> None:
        core = env.unwrapped
        super().__init__(env, ActionStages(1.0, params or ShieldParams.of(core)))
        self.shield = self.stages.shield
        self.params = self.shield.params
