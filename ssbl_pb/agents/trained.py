"""Loading trained SB3 models (PPO / RecurrentPPO) with their observation normalisation as ``Policy``s."""

from __future__ import annotations

import dataclasses
import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from ..core.actions import ActionStages
from ..core.layouts import GroupModel as EnvGroups
from ..core.observation import BASE_SIZE, MEMBER_ORDERS, OBS_SIZE
from ..core.shield import ShieldParams
from ..core.task import TaskParams
from ..errors import UserError
from ..files import copy_file, write_text
from ..params import RobotParams, SocialParams, parse_yaml
from ..policies import SHIPPED, SHIPPED_ENCODERS
from .policies import BASELINES, Policy

MODEL_FILES = ("model.zip", "best/model.zip")  # a run directory: its final model, else its best one
STEP_STAMP = "ssbl_step"  # the model's step, recorded in the normalisation saved with it (training.callbacks)


class ModelError(UserError):
    """A model file or run directory cannot be used; the message names the file and the problem."""


def resolve_model(spec: str) -> tuple[Path, Path | None, dict[str, Any]]:
    """(model zip, normalisation pickle or None, run config) for a shipped name, a run dir or a .zip path.

    A run directory gives its final model (``model.zip``; ``RUN/best`` names the best evaluated one); the
    normalisation statistics and config are those saved beside the chosen model (a training checkpoint,
    ``RUN/checkpoints/ckpt_N.zip``: its ``ckpt_N_vecnormalize.pkl`` and the run's config)."""
    path = SHIPPED.get(spec, Path(spec))
    if spec in SHIPPED and not path.is_dir():
        raise ModelError(f"shipped policy '{spec}' is missing: expected {path}/model.zip")
    if path.is_dir():
        found = [path / f for f in MODEL_FILES if (path / f).is_file()]
        if not found:
            raise ModelError(f"{path}: no model in this directory (expected one of {list(MODEL_FILES)})")
        model = found[0]
    else:
        model = path
        if not model.is_file():
            raise ModelError(f"{model}: model file not found")
    folder = model.parent
    norm = folder / "vecnormalize.pkl"
    if model.with_name(f"{model.stem}_vecnormalize.pkl").is_file():  # a checkpoint's own
        norm = model.with_name(f"{model.stem}_vecnormalize.pkl")
    config = read_run_config((folder.parent if folder.name == "checkpoints" else folder) / "config.yaml")
    check_model_set(model, norm if norm.is_file() else None)
    return model, (norm if norm.is_file() else None), config


def read_run_config(path: Path) -> dict[str, Any]:
    """A model's ``config.yaml`` as a mapping (``{}`` when there is none); a corrupt one is a ``ModelError``."""
    if not path.is_file():
        return {}
    try:
        config = parse_yaml(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: not readable YAML ({' '.join(str(exc).split())})") from exc
    if config is not None and not isinstance(config, dict):
        raise ModelError(f"{path}: expected a mapping of training settings (tools/train_pb.py writes one), got a "
                         f"{type(config).__name__}")
    return config or {}


def _model_step(model: Path) -> int | None:
    """The step SB3 recorded in a model archive (``num_timesteps`` in its ``data``), None when unreadable."""
    try:
        with zipfile.ZipFile(model) as z:
            step = json.loads(z.read("data"))["num_timesteps"]
    except (OSError, KeyError, ValueError, TypeError, zipfile.BadZipFile):
        return None
    return step if isinstance(step, int) else None


def _norm_step(norm: Path) -> int | None:
    """The step the normalisation was saved at (``STEP_STAMP``; None for files saved before it was recorded)."""
    try:
        with open(norm, "rb") as fh:
            step = vars(pickle.load(fh)).get(STEP_STAMP)  # vars: a VecNormalize without its venv recurses in getattr
    except (OSError, EOFError, ValueError, TypeError, AttributeError, ImportError, pickle.UnpicklingError):
        return None  # an unreadable file is reported when it is loaded
    return step if isinstance(step, int) else None


def check_model_set(model: Path, norm: Path | None) -> None:
    """Refuse a model whose saved parts come from different moments (a training run killed while saving them):
    the normalisation (``STEP_STAMP``) and ``eval.json`` beside the model must record the model's step, and a
    model saved by training (a run directory, or its ``best/``) must have its normalisation beside it."""
    folder = model.parent
    by_training = (folder / "baselines.json").is_file() or (
        folder.name == "best" and (folder.parent / "config.yaml").is_file())
    if norm is None and by_training:
        raise ModelError(f"{folder}: {model.name} has no vecnormalize.pkl beside it (a save was interrupted); "
                         f"{_remedy(folder)}")
    step = _model_step(model)
    if step is None:
        return
    parts = {}
    if norm is not None and (n := _norm_step(norm)) is not None:
        parts[norm.name] = n
    ev = folder / "eval.json"
    if ev.is_file():
        try:
            parts[ev.name] = json.loads(ev.read_text()).get("step")
        except (OSError, ValueError, AttributeError):
            parts[ev.name] = None
    wrong = {k: v for k, v in parts.items() if v != step}
    if wrong:
        other = ", ".join(f"{k} from step {v}" if v is not None else f"{k} unreadable" for k, v in wrong.items())
        raise ModelError(f"{folder}: its parts disagree ({model.name} from step {step}, {other}): a save was "
                         f"interrupted; {_remedy(folder)}")


def _remedy(folder: Path) -> str:
    if folder.name == "best":
        return f"use the run's final model ({folder.parent}) or another checkpoint"
    return f"finish the run with python tools/train_pb.py --resume {folder}"


OBSERVATION_KEYS = ("waypoints", "waypoints_near_group", "member_order")  # env arguments that change what a policy
#                                                                             observes


@dataclasses.dataclass(frozen=True)
class PolicyView:
    """How a policy's Vector observation is made, beyond the env (config ``env``'s ``OBSERVATION_KEYS``); deploy
    builds the same from its perception."""

    waypoints: bool = False  # in rooms with obstacles the slot's entries show the way round them (``planner``)
    waypoints_near_group: bool = False  # ... up to the group's keep-out disc
    member_order: str = "nearest"  # the member blocks' order (``observation.MEMBER_ORDERS``)


DEFAULT_VIEW = PolicyView()


def policy_view(spec: str) -> PolicyView:
    """The ``PolicyView`` of a trained model (a baseline's: the defaults); a member order it does not know is
    refused, naming the model's config."""
    seen = policy_env_kwargs(spec)
    order = seen.get("member_order", "nearest")
    if order not in MEMBER_ORDERS:
        raise ModelError(f"{resolve_model(spec)[0].parent / 'config.yaml'}: env.member_order {order!r}: expected one "
                         f"of {list(MEMBER_ORDERS)}")
    return PolicyView(bool(seen.get("waypoints", False)), bool(seen.get("waypoints_near_group", False)), order)


def policy_env_kwargs(spec: str) -> dict[str, Any]:
    """The env a trained model needs beyond the defaults: what its observation was made of (config ``env``'s
    ``OBSERVATION_KEYS``: the waypoints in furnished rooms); for a model on a frozen autoencoder (config
    ``encoder`` conv / saev), its camera mode, image size, features' low-pass and encoder checkpoint (looked up
    beside the model, then beside its run directory, then as written); ``{}`` for a baseline."""
    if spec in BASELINES:
        return {}
    model, _, config = resolve_model(spec)
    env = config.get("env") or {}
    seen = {k: env[k] for k in OBSERVATION_KEYS if k in env}
    if config.get("encoder") not in ("conv", "saev"):
        return seen
    name = config.get("encoder_checkpoint") or ""
    if not name:
        name = str(SHIPPED_ENCODERS.get(config["encoder"], ""))
    found = [p for p in (model.parent / name, model.parent.parent / name, Path(name)) if name and p.is_file()]
    if not found:
        raise ModelError(f"{model}: its encoder checkpoint {name!r} (config encoder_checkpoint) is not beside the "
                         f"model nor at that path")
    size = int(config.get("camera_size", 84))
    smoothing = {"feature_smoothing": float(config["feature_smoothing"])} if config.get("feature_smoothing", 1) != 1 \
        else {}
    return {**seen, "obs_mode": config["obs_mode"], "camera_width": size, "camera_height": size,
            "encoder": str(found[0]), **smoothing}


def copy_policy(spec: str, dest: Path) -> list[str]:
    """Copy what a trained policy needs into the folder ``dest`` (``model.zip``, ``vecnormalize.pkl``,
    ``config.yaml`` and, for a policy on a frozen autoencoder, its checkpoint as ``encoder.pt`` with the config
    pointing there), so that ``dest`` works as a policy by itself; returns the file names written."""
    model, norm, config = resolve_model(spec)
    if norm is None:
        raise ModelError(f"{model.parent}: no vecnormalize.pkl beside the model")
    kwargs = policy_env_kwargs(spec)
    copy_file(model, dest / "model.zip")
    copy_file(norm, dest / "vecnormalize.pkl")
    if "encoder" in kwargs:
        copy_file(Path(kwargs["encoder"]), dest / "encoder.pt")
        config = {**config, "encoder_checkpoint": "encoder.pt"}
    write_text(dest / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    return ["model.zip", "vecnormalize.pkl", "config.yaml"] + (["encoder.pt"] if "encoder" in kwargs else [])


class TrainedPolicy(Policy):
    """An SB3 model behind the common ``predict`` signature; observations are normalised as in training."""

    def __init__(self, model: Any, normalizer: Any = None, recurrent: bool = False, smoothing: float = 1.0,
                 shield: bool = False, shield_params: Any = None) -> None:
        """``smoothing`` and ``shield`` are the agent's action stages as in training (config ``action_smoothing``,
        ``safety_shield``); the shield needs Vector observations and uses ``shield_params`` (a ``ShieldParams``;
        default: Pepper's default limits)."""
        self.model = model
        self.normalizer = normalizer
        self.recurrent = recurrent
        self.observation_space = model.observation_space
        vector = (isinstance(model.observation_space, gym.spaces.Box)
                  and model.observation_space.shape in ((OBS_SIZE,), (BASE_SIZE,)))
        # a model trained before the range scan reads (and is shielded on) the first 40 entries only
        self.base_only = vector and model.observation_space.shape == (BASE_SIZE,)
        if shield and not vector:
            raise ModelError("the safety shield needs a Vector-observation model")
        self.stages = ActionStages(smoothing, (shield_params or ShieldParams()) if shield else None)
        self.filter, self.shield = self.stages.filter, self.stages.shield  # what each did last: the logs read them

    def reset(self) -> None:
        """Start of an episode: clears the action filter."""
        self.stages.reset()

    def normalize(self, obs: Any) -> Any:
        return obs if self.normalizer is None else self.normalizer.normalize_obs(obs)

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        if self.base_only:
            observation = np.asarray(observation)[..., :BASE_SIZE]
        obs = self.normalize(observation)
        if self.recurrent:
            action, state = self.model.predict(obs, state=state, episode_start=episode_start,
                                               deterministic=deterministic)
        else:
            action, state = self.model.predict(obs, deterministic=deterministic)[0], None
        return self.stages(observation, action), state


def _channel_first(space: gym.Space) -> gym.Space:
    """SB3 stores image spaces channel-first (VecTransposeImage); do the same to an env's space."""
    if isinstance(space, gym.spaces.Dict):
        return gym.spaces.Dict({k: _channel_first(v) for k, v in space.spaces.items()})
    if isinstance(space, gym.spaces.Box) and space.dtype == np.uint8 and len(space.shape) == 3:
        h, w, c = space.shape
        return gym.spaces.Box(0, 255, (c, h, w), np.uint8)
    return space


def _compatible(model_space: gym.Space, env_space: gym.Space) -> bool:
    if isinstance(model_space, gym.spaces.Box) and model_space.shape == (BASE_SIZE,):  # before the range scan
        return isinstance(env_space, gym.spaces.Box) and env_space.shape in ((BASE_SIZE,), (OBS_SIZE,))
    return model_space == env_space or model_space == _channel_first(env_space)


def shield_at_place(spec: str) -> bool:
    """Whether a trained model's shield keeps its place's clearance and slows its arrival near the place (config
    ``shield_at_place``, ``ShieldParams.from_env``; off for models trained before it and for baselines)."""
    return spec not in BASELINES and bool(resolve_model(spec)[2].get("shield_at_place", False))


def load_trained(spec: str, observation_space: gym.Space | None = None, shield: bool | None = None,
                 shield_params: Any = None) -> TrainedPolicy:
    """Load a trained model (shipped name, run directory or .zip); checks it fits ``observation_space``.

    ``shield``: the safety shield on or off; None (default) uses it as the model was trained (config
    ``safety_shield``). ``shield_params``: its limits (``ShieldParams.from_env`` for a calibrated robot, with the
    model's ``shield_at_place``); None: Pepper's defaults, likewise."""
    model_path, norm_path, config = resolve_model(spec)
    if not zipfile.is_zipfile(model_path):
        raise ModelError(f"{model_path}: not a saved SB3 model (expected a .zip archive)")
    recurrent = config.get("policy", "ff") == "lstm"
    try:
        if recurrent:
            from sb3_contrib import RecurrentPPO as Algo
        else:
            from stable_baselines3 import PPO as Algo
        model = Algo.load(str(model_path), device="cpu")
    except Exception as exc:  # corrupt archive, wrong algorithm, ...
        raise ModelError(f"{model_path}: cannot load the model ({type(exc).__name__}: {exc})") from exc
    if observation_space is not None and not _compatible(model.observation_space, observation_space):
        mode = config.get("obs_mode", "unknown")
        raise ModelError(f"{model_path}: the model was trained for observations {model.observation_space} "
                         f"(obs_mode '{mode}'), not {observation_space}")
    normalizer = None
    if norm_path is not None:
        try:
            with open(norm_path, "rb") as fh:
                normalizer = pickle.load(fh)
        except Exception as exc:
            raise ModelError(f"{norm_path}: cannot read the normalisation statistics ({exc})") from exc
        normalizer.training = False
    if shield is None:
        shield = bool(config.get("safety_shield", False)) and config.get("obs_mode", "vector") == "vector"
    if shield and shield_params is None:
        shield_params = ShieldParams.from_env(RobotParams(), SocialParams(), TaskParams(), shield_at_place(spec))
    return TrainedPolicy(model, normalizer, recurrent, float(config.get("action_smoothing", 1.0)), shield,
                         shield_params)


def policy_groups(spec: str) -> str:
    """The group model (``core.layouts.GROUP_MODELS``) the policy ``spec`` was trained on: its run config's
    ``env.groups``; a baseline, or a config without one, the env's default."""
    if spec in BASELINES:
        return EnvGroups().name
    env = resolve_model(spec)[2].get("env") or {}
    groups = env.get("groups") if isinstance(env, dict) else None
    return EnvGroups(str(groups)).name if groups else EnvGroups().name
