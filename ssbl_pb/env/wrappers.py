"""Observation modes as wrappers of the one core env (paper III-B: Vector, CameraOnly, CameraSpeed)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

OBS_MODES = ("vector", "camera", "camera_speed")


class CameraObservation(gym.ObservationWrapper):
    """Pepper's first-person RGB image (H, W, 3) uint8 instead of the vector (CameraOnly mode)."""

    def __init__(self, env: gym.Env, width: int = 84, height: int = 84, projection: list[float] | None = None):
        super().__init__(env)
        if not (isinstance(width, int) and isinstance(height, int) and 8 <= width <= 1024 and 8 <= height <= 1024):
            raise ValueError(f"camera size {width}x{height}: expected integers in [8, 1024]")
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
        # indices 5-7 of the Vector layout hold the normalised body velocity (see env.observation)
        return {"image": self.image(), "speed": np.clip(observation[5:8], -1.5, 1.5).astype(np.float32)}


def wrap_obs_mode(env: gym.Env, obs_mode: str, width: int = 84, height: int = 84) -> gym.Env:
    """The env seen through ``obs_mode``."""
    if obs_mode == "vector":
        return env
    if obs_mode == "camera":
        return CameraObservation(env, width, height)
    if obs_mode == "camera_speed":
        return CameraSpeedObservation(env, width, height)
    raise ValueError(f"obs_mode {obs_mode!r}: expected one of {OBS_MODES}")
