"""Camera modes through a frozen autoencoder (paper III-B, SSBL's first stage): features instead of pixels.

The encoder of a trained autoencoder (``perception.autoencoding.ae_train``) turns each first-person image into its code:
SAEV's 16 keypoints (x, y, presence) or the conv AE's dense code. CameraSpeed appends the robot's (forward,
sideways) speed, as the original did. Two wrappers emit the same observation space:

* ``EncodedVecEnv`` (training): encodes the images of all envs of a VecEnv in one batch per step, so PPO's
  updates never run the CNN (and neither does anything else: the policy sees features only);
* ``EncodedObservation`` (one env: evaluation, videos, deploy): the same encoder on one image per step.

The encoder is frozen: ``FrozenEncoder`` holds it in eval mode (BatchNorm running statistics, no dropout)
whatever ``train()`` is called with and keeps its weights out of every optimiser.

``feature_smoothing`` (config key; 1 = off) low-passes the code over an episode's frames before the policy sees it,
``y_t = y_{t-1} + alpha (code_t - y_{t-1})`` (the speed is not filtered): SAEV's keypoints jitter from frame to
frame, and a feed-forward policy passes the jitter on to the wheels (docs/decisions.md, "The jerk cost in Table I").

An encoder only reads images like those it learned from, so the camera it learned through (its field of view,
recorded from the frames file) is the camera of every env it runs in (``with_encoder_camera``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from torch import nn

from ...core.actions import ExponentialFilter
from ...errors import UserError
from ...params import RobotParams
from ...perception.autoencoding.ae_train import checkpoint_info, load_autoencoder
from ...perception.autoencoding.autoencoders import Autoencoder, to_input
from ...perception.camera import PinholeCamera

ENCODED_ARCHS = ("conv", "saev")


class FrozenEncoder(nn.Module):
    """A trained autoencoder used as a fixed feature extractor: uint8 images (B, S, S, 3) -> features (B, F)."""

    def __init__(self, model: Autoencoder) -> None:
        super().__init__()
        self.model = model
        for p in self.model.parameters():
            p.requires_grad_(False)
        super().train(False)

    def train(self, mode: bool = True) -> FrozenEncoder:
        """Stays in eval mode: SB3 calls ``train()`` on its policy before every update, which would switch
        BatchNorm back to batch statistics and dropout on."""
        return super().train(False)

    @property
    def arch(self) -> str:
        return self.model.arch

    @property
    def resolution(self) -> int:
        return self.model.size.input_size

    @property
    def feature_dim(self) -> int:
        return self.model.feature_dim

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.model.encode(to_input(images))

    def encode(self, images: np.ndarray) -> np.ndarray:
        """Features (B, F) float32 of uint8 images (B, S, S, 3)."""
        with torch.inference_mode():
            return self(torch.from_numpy(np.ascontiguousarray(images))).numpy()


def load_encoder(path: str | Path, resolution: int | None = None, arch: str | None = None) -> FrozenEncoder:
    """The frozen encoder of a ``tools/train_ae.py`` checkpoint; ``resolution`` is the camera's image side."""
    if resolution is not None:
        have = checkpoint_info(path)["resolution"]
        if have != resolution:
            raise UserError(f"encoder checkpoint {path} takes {have}x{have} images, the camera renders "
                            f"{resolution}x{resolution} (set camera_size: {have})")
    return FrozenEncoder(load_autoencoder(path, arch=arch))


def encoder_camera(path: str | Path) -> dict[str, float]:
    """The camera (``RobotParams`` keys) an encoder's frames were seen through: its field of view; ``{}`` for a
    checkpoint written before it was recorded (those learned through Pepper's camera, the default)."""
    hfov = (checkpoint_info(path)["extra"].get("summary") or {}).get("camera_hfov_deg")
    return {} if hfov is None else {"camera_hfov_deg": float(hfov)}


def encoder_hfov(path: str | Path) -> float:
    """The horizontal field of view (degrees) an encoder learned through (Pepper's when none was recorded)."""
    return encoder_camera(path).get("camera_hfov_deg", RobotParams().camera_hfov_deg)


# A calibrated camera (``camera_yaml``) may differ from the encoder's by this much in magnification,
# tan(hfov/2) ratio: 5 % moves a keypoint at the image border by under 2 px of a 64-px frame, while Pepper's
# nominal 56.3 deg against a calibrated unit's few-percent spread stays within it (our choice; the paper has none).
CALIBRATED_MAGNIFICATION_TOL = 0.05


def check_calibrated_camera(camera_yaml: str | Path, path: str | Path) -> None:
    """Refuse a calibrated camera whose field of view is not the one the encoder learned through."""
    learned = encoder_hfov(path)
    have = PinholeCamera.from_yaml(camera_yaml).fov_deg()[0]
    ratio = math.tan(math.radians(learned) / 2) / math.tan(math.radians(have) / 2)
    if abs(ratio - 1) > CALIBRATED_MAGNIFICATION_TOL:
        raise UserError(f"camera_yaml {camera_yaml}: a {have:.1f} deg camera, the encoder {path} learned from "
                        f"frames of a {learned:g} deg camera (people {ratio:.2f}x their size there; at most "
                        f"{CALIBRATED_MAGNIFICATION_TOL:.0%} apart); collect frames through this camera "
                        f"(tools/collect_frames.py --camera-hfov {have:.1f}) and train the encoder on them")


def with_encoder_camera(kwargs: dict[str, Any], path: str | Path) -> dict[str, Any]:
    """Env keyword arguments whose ``robot`` camera is the encoder's; another one set there is an error, and so
    is a calibrated camera (``camera_yaml``, whose field of view then applies) too far from it."""
    if kwargs.get("camera_yaml") is not None:
        check_calibrated_camera(kwargs["camera_yaml"], path)
    cam = encoder_camera(path)
    if not cam:
        return kwargs
    robot = kwargs.get("robot") or {}
    robot = dataclasses.asdict(robot) if isinstance(robot, RobotParams) else dict(robot)
    for key, value in cam.items():
        if key in robot and not math.isclose(float(robot[key]), value, abs_tol=1e-3):
            raise UserError(f"robot {key} {robot[key]}: the encoder {path} learned from frames of a {value:g} deg "
                            f"camera (tools/collect_frames.py --camera-hfov); leave {key} unset or collect frames "
                            f"and train the encoder at {robot[key]}")
    return {**kwargs, "robot": {**robot, **cam}}


def features_space(encoder: FrozenEncoder, with_speed: bool) -> gym.spaces.Box:
    """The encoded observation: the code, then (forward, sideways) speed in CameraSpeed mode."""
    n = encoder.feature_dim + (2 if with_speed else 0)
    return gym.spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)


def _split(obs: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """(images, speed or None) of a camera / camera_speed observation (single or batched)."""
    if isinstance(obs, dict):
        return obs["image"], np.asarray(obs["speed"], dtype=np.float32)[..., :2]
    return obs, None


def _with_speed(features: np.ndarray, speed: np.ndarray | None) -> np.ndarray:
    out = features if speed is None else np.concatenate([features, speed], axis=-1)
    return out.astype(np.float32, copy=False)


def check_feature_smoothing(alpha: Any, where: str = "feature_smoothing") -> float:
    """``alpha`` of the features' low-pass as a float in (0, 1], else a ``UserError`` naming ``where``."""
    if isinstance(alpha, bool) or not isinstance(alpha, int | float) or not 0 < alpha <= 1:
        raise UserError(f"{where} {alpha!r}: expected a number in (0, 1] (the weight of the newest frame's "
                        "features; 1 = no filter)")
    return float(alpha)


def feature_filter(alpha: float) -> ExponentialFilter | None:
    """The low-pass of the encoded features (None for ``alpha`` 1: the features as encoded)."""
    alpha = check_feature_smoothing(alpha)
    return ExponentialFilter(alpha) if alpha < 1.0 else None


def low_pass_episodes(features: np.ndarray, episode: np.ndarray, alpha: float) -> np.ndarray:
    """Consecutive frames' features (N, F) as the wrappers' low-pass gives them, restarting at each new
    ``episode`` number (offline, e.g. on a frames file)."""
    filt = feature_filter(alpha)
    if filt is None:
        return np.asarray(features, dtype=np.float32)
    out = np.empty_like(features, dtype=np.float32)
    for t, x in enumerate(features):
        if t and episode[t] != episode[t - 1]:
            filt.reset()
        out[t] = filt(x)
    return out


def _check_camera_space(space: gym.Space, encoder: FrozenEncoder) -> bool:
    """Whether ``space`` is CameraSpeed's (else CameraOnly's); raises unless its images fit the encoder."""
    image = space["image"] if isinstance(space, gym.spaces.Dict) else space
    if not (isinstance(image, gym.spaces.Box) and image.dtype == np.uint8 and len(image.shape) == 3):
        raise UserError(f"an encoder needs camera observations (obs_mode camera or camera_speed), not {space}")
    h, w, _ = image.shape
    if (h, w) != (encoder.resolution, encoder.resolution):
        raise UserError(f"the camera renders {w}x{h}, the {encoder.arch} encoder takes "
                        f"{encoder.resolution}x{encoder.resolution} (set camera_size: {encoder.resolution})")
    return isinstance(space, gym.spaces.Dict)


class EncodedObservation(gym.ObservationWrapper):
    """One camera env's images replaced by the frozen encoder's features (plus speed in CameraSpeed mode)."""

    def __init__(self, env: gym.Env, encoder: FrozenEncoder, feature_smoothing: float = 1.0) -> None:
        super().__init__(env)
        self.encoder = encoder
        self.filter = feature_filter(feature_smoothing)
        self.with_speed = _check_camera_space(env.observation_space, encoder)
        self.observation_space = features_space(encoder, self.with_speed)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        if self.filter is not None:
            self.filter.reset()
        return super().reset(**kwargs)

    def observation(self, observation: Any) -> np.ndarray:
        images, speed = _split(observation)
        features = self.encoder.encode(images[None])[0]
        return _with_speed(features if self.filter is None else self.filter(features), speed)


class EncodedVecEnv(VecEnvWrapper):
    """A VecEnv of camera envs whose images are encoded together, once per step (terminal observations too)."""

    def __init__(self, venv: VecEnv, encoder: FrozenEncoder, feature_smoothing: float = 1.0) -> None:
        self.encoder = encoder
        self.filter = feature_filter(feature_smoothing)
        self.with_speed = _check_camera_space(venv.observation_space, encoder)
        super().__init__(venv, observation_space=features_space(encoder, self.with_speed))

    def reset(self) -> np.ndarray:
        if self.filter is not None:
            self.filter.reset()
        images, speed = _split(self.venv.reset())
        features = self.encoder.encode(images)
        return _with_speed(features if self.filter is None else self.filter(features), speed)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rewards, dones, infos = self.venv.step_wait()
        images, speed = _split(obs)
        features = self.encoder.encode(images)
        ends = [i for i, info in enumerate(infos) if "terminal_observation" in info]
        if ends:  # PPO bootstraps truncated episodes from these: they must be features too
            last = [infos[i]["terminal_observation"] for i in ends]
            batch = {k: np.stack([o[k] for o in last]) for k in last[0]} if isinstance(last[0], dict) \
                else np.stack(last)
            last_images, last_speed = _split(batch)
            last_features = self.encoder.encode(last_images)
            if self.filter is not None:  # an episode's last frame, filtered with its episode's past
                whole = features.copy()
                whole[ends] = last_features
                last_features = self.filter.peek(whole)[ends]
            for i, f in zip(ends, _with_speed(last_features, last_speed), strict=True):
                infos[i]["terminal_observation"] = f
        if self.filter is not None:
            self.filter.reset(rows=[i for i, d in enumerate(dones) if d])  # a new episode's first frame
            features = self.filter(features)
        return _with_speed(features, speed), rewards, dones, infos
