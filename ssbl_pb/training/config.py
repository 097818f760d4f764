"""Training configuration: a YAML file (``configs/*.yaml``) over dataclass defaults; unknown keys are rejected.

Defaults start from the original code's PPO settings (shared/reference/peppersocial.md, "PPO") and depart
where this 2-core CPU machine needs it:

=================  ==================  ===========================================================
setting            original            here, and why
=================  ==================  ===========================================================
learning rate      1e-4                3e-4: 10-minute budget instead of 3e6 steps
batch / buffer     2048 / 10240        minibatch 256 / 8 envs x 256 steps = 2048 per update
epochs             3                   5: fewer, cheaper environment steps per update
hidden layers      3 x 512             2 x 128: CPU forward passes dominate the step cost
gamma / lambda     0.99 / 0.95         same
clip / entropy     0.2 / 1e-3          same
obs normalisation  on                  on (VecNormalize, rewards too; ``normalize_obs``: auto, off for AE features)
LSTM               memory 256, seq 64  hidden 128 (``policy: lstm``)
action mean        not given           tanh-bounded (``ppo.bounded_mean``, training/policies.py)
=================  ==================  ===========================================================
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from pathlib import Path
from typing import Any

import yaml

from ..core.reward import RewardWeights
from ..env.engine.env_params import parse_env_params
from ..env.gymenv.approach import ApproachGroupEnv, make_env
from ..errors import UserError
from ..files import write_text
from ..params import ConfigError, _check, from_dict, load_yaml, parse_yaml
from ..policies import SHIPPED_ENCODERS

OBS_MODES = ("vector", "camera", "camera_speed")
ENCODERS = ("none", "cnn", "conv", "saev")  # cnn: end-to-end NatureCNN; conv / saev: a frozen autoencoder
POLICIES = ("ff", "lstm")
VEC_ENVS = ("auto", "batched", "dummy", "subproc")
SEED_MAX = 2**32 - 1  # SB3 seeds numpy's legacy generator, which takes 0 .. 2**32 - 1


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    learning_rate: float = 3e-4
    # anneal linearly to this by the end of the run (None: constant); a short run's last updates then stop
    # undoing what it learned (configs/demo.yaml)
    learning_rate_end: float | None = None
    n_steps: int = 256  # per env
    batch_size: int = 256
    n_epochs: int = 5
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 1e-3
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    net_arch: tuple[int, ...] = (128, 128)
    lstm_hidden_size: int = 128
    log_std_init: float = -0.5  # SB3 default 0 (std 1) saturates [-1, 1] actions and makes stopping rare
    bounded_mean: bool = True  # tanh on the Gaussian mean (training/policies.py): keeps saturated axes exploring
    # with --init-from: the action std restarts at this (null: the source's). The shipped policy's has shrunk to
    # 0.055 of the action range; fine-tunes from it hardly explore (docs/benchmarks_movenet.md)
    restart_std: float | None = None

    def __post_init__(self) -> None:
        for name in ("learning_rate", "gamma", "gae_lambda", "clip_range"):
            v = getattr(self, name)
            _check(isinstance(v, int | float) and 0 < v <= 1, "ppo", name, v, "a number in (0, 1]")
        end = self.learning_rate_end
        _check(end is None or (isinstance(end, int | float) and 0 < end <= 1), "ppo", "learning_rate_end", end,
               "a number in (0, 1] or null (constant)")
        for name in ("n_steps", "batch_size", "n_epochs", "lstm_hidden_size"):
            v = getattr(self, name)
            _check(isinstance(v, int) and v >= 1, "ppo", name, v, "an integer >= 1")
        _check(all(isinstance(h, int) and h > 0 for h in self.net_arch), "ppo", "net_arch", self.net_arch,
               "a list of positive layer sizes")
        _check(isinstance(self.bounded_mean, bool), "ppo", "bounded_mean", self.bounded_mean, "true or false")
        std = self.restart_std
        _check(std is None or (isinstance(std, int | float) and 0 < std <= 1), "ppo", "restart_std", std,
               "a number in (0, 1] or null (the source's)")


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """One training run. ``env`` holds keyword arguments of the env (world/robot/social/task dicts)."""

    name: str = "ppo_vector"
    obs_mode: str = "vector"
    encoder: str = "none"
    policy: str = "ff"
    scenario: str = "default"
    n_envs: int = 8
    vec_env: str = "auto"  # batched (Vector mode: all copies in one compiled step), dummy (one process, one env
    #                        object per copy), subproc (one process per copy); auto = batched where it applies
    total_steps: int = 300_000
    seed: int = 0
    device: str = "cpu"
    torch_threads: int = 1
    reward: dict[str, float] = dataclasses.field(default_factory=dict)
    # reward weights that ramp linearly from [start, end] over the first ``reward_ramp_fraction`` of training
    reward_ramp: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    reward_ramp_fraction: float = 0.5
    env: dict[str, Any] = dataclasses.field(default_factory=dict)
    ppo: PPOConfig = dataclasses.field(default_factory=PPOConfig)
    eval_every: int = 20_000
    eval_episodes: int = 30
    eval_seed: int = 100_000  # evaluation seeds are disjoint from training and from tools/evaluate's default
    checkpoint_every: int = 50_000
    baseline_episodes: int = 20  # episodes of the random and SFFM baselines drawn on the learning curve
    camera_size: int = 84
    # the frozen autoencoder of encoder conv / saev (tools/train_ae.py); empty = the shipped SAEV encoder
    encoder_checkpoint: str = ""
    # low-pass of the frozen encoder's features over an episode, the newest frame's weight (env.gymenv.encoded; 1 = off)
    feature_smoothing: float = 1.0
    action_smoothing: float = 0.4  # agent-side action filter (core.actions.ActionStages); 1.0 = off
    safety_shield: bool = True  # agent-side safety shield (core.shield), the last action stage; it reads the
    #                             Vector observation, so camera modes train without it
    # VecNormalize's running standardisation of the observation (the original's "normalize: true"); false feeds
    # it raw (reward normalisation stays); unset (auto): on, except for a frozen encoder's features, which train
    # far better raw (docs/decisions.md, "Camera state representations"; Table I's camera rows)
    normalize_obs: bool | None = None
    shield_at_place: bool = False  # near its place the shield keeps the place's clearance from the members and
    #                                slows the arrival (ShieldParams.place_clearance, place_arrival_speed; on for
    #                                the shipped vector); tools and deploy too
    # reward per step of -shield_penalty x how far the shield moved the action executed (``ShieldRecord.correction``;
    # not one the observation model's search or looks replaced): a policy that leans on its shield pays for it, as
    # Alshiekh et al. (AAAI 2018, "Safe reinforcement learning via shielding") punish the actions a shield replaces.
    # 0: off (ours; the paper has no shield)
    shield_penalty: float = 0.0

    @property
    def vec_env_kind(self) -> str:
        """The VecEnv training builds: ``vec_env``, with auto resolved (batched for the Vector mode)."""
        if self.vec_env != "auto":
            return self.vec_env
        return "batched" if self.obs_mode == "vector" else "dummy"

    @property
    def encoder_file(self) -> str | None:
        """The autoencoder checkpoint the camera images go through (encoder conv / saev), else None."""
        if self.encoder not in ("conv", "saev"):
            return None
        if self.encoder_checkpoint:
            return self.encoder_checkpoint
        return str(SHIPPED_ENCODERS.get(self.encoder, ""))

    @property
    def standardises_obs(self) -> bool:
        """``normalize_obs`` with auto resolved: off for a frozen encoder's features, else on."""
        return self.normalize_obs if self.normalize_obs is not None else not self.encoder_file

    @property
    def policy_obs_mode(self) -> str:
        """The observation the policy network sees: encoded camera modes give it a flat vector."""
        return "vector" if self.encoder_file else self.obs_mode

    @property
    def shield_active(self) -> bool:
        """Whether training (and its evaluations) put the safety shield in the loop."""
        return self.safety_shield and self.obs_mode == "vector"

    def __post_init__(self) -> None:
        _check(self.obs_mode in OBS_MODES, "config", "obs_mode", self.obs_mode, f"one of {OBS_MODES}")
        _check(self.encoder in ENCODERS, "config", "encoder", self.encoder, f"one of {ENCODERS}")
        if self.obs_mode == "vector":
            _check(self.encoder == "none", "config", "encoder", self.encoder, "'none' for obs_mode vector")
        else:
            _check(self.encoder != "none", "config", "encoder", self.encoder,
                   f"'cnn', 'conv' or 'saev' for obs_mode {self.obs_mode}")
            self._check_encoder()
        _check(self.policy in POLICIES, "config", "policy", self.policy, f"one of {POLICIES}")
        _check(self.vec_env in VEC_ENVS, "config", "vec_env", self.vec_env, f"one of {VEC_ENVS}")
        if self.vec_env == "batched":
            _check(self.obs_mode == "vector", "config", "vec_env", self.vec_env,
                   f"'auto', 'dummy' or 'subproc' for obs_mode {self.obs_mode} (batched steps the Vector mode only)")
        for name in ("n_envs", "total_steps", "eval_every", "eval_episodes", "checkpoint_every", "torch_threads"):
            v = getattr(self, name)
            _check(isinstance(v, int) and v >= 1, "config", name, v, "an integer >= 1")
        _check(isinstance(self.seed, int) and not isinstance(self.seed, bool) and 0 <= self.seed <= SEED_MAX, "config",
               "seed", self.seed, f"an integer in [0, {SEED_MAX}]")
        _check(isinstance(self.eval_seed, int) and not isinstance(self.eval_seed, bool) and self.eval_seed >= 0,
               "config", "eval_seed", self.eval_seed, "an integer >= 0")
        _check(isinstance(self.safety_shield, bool), "config", "safety_shield", self.safety_shield, "true or false")
        _check(self.normalize_obs is None or isinstance(self.normalize_obs, bool), "config", "normalize_obs",
               self.normalize_obs, "true, false or unset (auto)")
        _check(isinstance(self.shield_at_place, bool), "config", "shield_at_place", self.shield_at_place,
               "true or false")
        _check(isinstance(self.shield_penalty, int | float) and math.isfinite(self.shield_penalty)
               and self.shield_penalty >= 0, "config", "shield_penalty", self.shield_penalty, "a number >= 0 (0: off)")
        _check(self.shield_penalty == 0 or self.shield_active, "config", "shield_penalty", self.shield_penalty,
               "0 without the safety shield (safety_shield: true and obs_mode: vector)")
        _check(isinstance(self.action_smoothing, int | float) and 0 < self.action_smoothing <= 1, "config",
               "action_smoothing", self.action_smoothing, "a number in (0, 1] (1 = off)")
        _check(not isinstance(self.feature_smoothing, bool) and isinstance(self.feature_smoothing, int | float)
               and 0 < self.feature_smoothing <= 1, "config", "feature_smoothing", self.feature_smoothing,
               "a number in (0, 1] (1 = off)")
        if self.feature_smoothing != 1:
            _check(self.encoder in ("conv", "saev"), "config", "feature_smoothing", self.feature_smoothing,
                   f"1 for encoder {self.encoder!r} (it filters a frozen encoder's features: encoder conv or saev)")
        _check(isinstance(self.env, dict), "config", "env", self.env, "a mapping of env arguments")
        unknown = sorted(set(self.env) - set(env_keys()))
        _check(not unknown, "config", "env", unknown, f"keys among {env_keys()} (the config sets obs_mode, "
               "scenario, reward and camera size itself)")
        from_dict(RewardWeights, self.reward, "config.reward")  # validates names and values early
        for key, value in self.reward_ramp.items():
            _check(isinstance(value, list | tuple) and len(value) == 2, "config", f"reward_ramp.{key}", value,
                   "[start, end]")
            from_dict(RewardWeights, {key: value[0]}, "config.reward_ramp")
            from_dict(RewardWeights, {key: value[1]}, "config.reward_ramp")
            # the ramp sets this weight during training: a different fixed value would be silently ignored
            _check(key not in self.reward or self.reward[key] == value[0], "config", f"reward.{key}",
                   self.reward.get(key), f"{value[0]}, the start of reward_ramp.{key} {list(value)} that sets it "
                   f"during training (to change it, set reward_ramp.{key}=[START,END], or reward_ramp={{}} to "
                   "train with fixed weights)")
        _check(isinstance(self.reward_ramp_fraction, int | float) and 0 < self.reward_ramp_fraction <= 1, "config",
               "reward_ramp_fraction", self.reward_ramp_fraction, "a number in (0, 1]")

    def _check_encoder(self) -> None:
        """The autoencoder checkpoint exists, is of the configured architecture and takes ``camera_size``."""
        path = self.encoder_file
        if path is None:
            return
        _check(bool(path) and Path(path).is_file(), "config", "encoder_checkpoint", self.encoder_checkpoint,
               f"an existing {self.encoder} checkpoint from tools/train_ae.py (none is shipped for {self.encoder})")
        # lazy: torch, for a frozen encoder only (the sweep CLI and train_pb import this module)
        from ..perception.autoencoding.ae_train import checkpoint_info

        info = checkpoint_info(path)
        _check(info["arch"] == self.encoder, "config", "encoder_checkpoint", path,
               f"a {self.encoder} checkpoint (encoder: {self.encoder}), it holds a {info['arch']} autoencoder")
        _check(info["resolution"] == self.camera_size, "config", "camera_size", self.camera_size,
               f"{info['resolution']}, the input resolution of encoder checkpoint {path}")
        from ..env.gymenv.encoded import with_encoder_camera  # lazy: torch and SB3, as above

        try:  # env.robot's camera may not contradict the one the encoder learned through
            with_encoder_camera(dict(self.env), path)
        except UserError as exc:
            raise ConfigError(f"config.env.{exc}") from exc

    @property
    def steps_per_update(self) -> int:
        return self.ppo.n_steps * self.n_envs


def env_keys() -> list[str]:
    """The env arguments a config's ``env:`` may set (``make_env``'s and the core env's, minus the config's own)."""
    own = {"obs_mode", "scenario", "reward", "camera_width", "camera_height", "render_mode", "render_width",
           "record", "self", "kwargs", "feature_smoothing"}
    names = [*inspect.signature(make_env).parameters, *inspect.signature(ApproachGroupEnv.__init__).parameters]
    return sorted(set(names) - own)


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """Command-line ``a.b=value`` pairs (values parsed as YAML) as a nested dict of config overrides."""
    pairs: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. reward.w1=0.1")
        pairs[key] = parse_yaml(raw)
    return nest_overrides(pairs)


def nest_overrides(pairs: dict[str, Any]) -> dict[str, Any]:
    """Dotted ``{"a.b": value}`` keys (``--set`` syntax, sweep grids) as the nested dict ``load_config`` takes."""
    out: dict[str, Any] = {}
    for key, value in pairs.items():
        node = out
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out


def load_config(path: str | Path | None, overrides: dict[str, Any] | None = None, env_check: bool = False
                ) -> TrainConfig:
    """Defaults, then the YAML file, then ``overrides`` (command-line flags); errors name the key, and the file
    when the file alone has the same error. ``env_check`` (a user's ``--config``) also checks the ``env:``
    sections (world, robot, social, task, rooms) as the env will, before anything is built."""
    file_data: dict[str, Any] = load_yaml(path) if path else {}
    data = dict(file_data)
    for key, value in (overrides or {}).items():
        if isinstance(value, dict):  # merged into the file's mapping; an empty one ({}) clears it
            data[key] = {**data.get(key, {}), **value} if value else {}
        else:
            data[key] = value
    try:
        return _checked(data, env_check)
    except ConfigError as exc:
        if path and not str(exc).startswith(str(path)) and str(exc) == _error(file_data, env_check):
            raise ConfigError(f"{path}: {exc}") from None  # the file's own value, not a flag's
        raise


def _checked(data: dict[str, Any], env_check: bool) -> TrainConfig:
    cfg = _from_dict(data, "config")
    if env_check:
        check_env(cfg)
    return cfg


def _error(data: dict[str, Any], env_check: bool) -> str | None:
    try:
        _checked(data, env_check)
    except ConfigError as exc:
        return str(exc)
    return None


def _from_dict(data: dict[str, Any], where: str) -> TrainConfig:
    try:
        return from_dict(TrainConfig, data, where)
    except TypeError as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def check_env(cfg: TrainConfig) -> None:
    """The config's env parameters as the env will check them (room size for its groups, group data, room
    YAMLs, the observation model), before anything is built."""
    # lazy: the tracker's filterpy and scipy (~1 s), for a config check only, not for tools that import this module
    from ..perception.groups.observation_model import PerceptionParams

    env = cfg.env
    try:
        PerceptionParams.of(env.get("perception"))
    except ConfigError as exc:  # the config's key is env.perception
        raise ConfigError(f"env.{exc}") from None
    parse_env_params(cfg.scenario, env.get("world"), env.get("robot"), env.get("social"), cfg.reward,
                     env.get("task"), env.get("groups"), env.get("groups_yaml"), env.get("room_yaml"),
                     env.get("furniture"))


def run_name(cfg: TrainConfig, file_cfg: TrainConfig, named: bool) -> TrainConfig:
    """Give a run whose flags changed the config file's observation mode or policy a name of its own (so that
    ``--policy lstm`` on a feed-forward config does not land in, or collide with, the feed-forward run)."""
    if named:
        return cfg
    suffix = "".join(f"_{getattr(cfg, k)}" for k in ("obs_mode", "policy") if getattr(cfg, k) != getattr(file_cfg, k))
    return dataclasses.replace(cfg, name=cfg.name + suffix) if suffix else cfg


def config_to_dict(cfg: TrainConfig) -> dict[str, Any]:
    d = dataclasses.asdict(cfg)
    d["ppo"]["net_arch"] = list(cfg.ppo.net_arch)
    return d


def env_kwargs(cfg: TrainConfig) -> dict[str, Any]:
    """``make_env``'s keyword arguments for the config's env (with the camera its frozen encoder learned through)."""
    kwargs = {"obs_mode": cfg.obs_mode, "scenario": cfg.scenario, "reward": dict(cfg.reward),
              "camera_width": cfg.camera_size, "camera_height": cfg.camera_size, **cfg.env}
    if cfg.encoder_file:  # the camera the encoder learned through
        from ..env.gymenv.encoded import with_encoder_camera  # lazy: torch and SB3, for a frozen encoder only

        kwargs = with_encoder_camera(kwargs, cfg.encoder_file)
    return kwargs


def save_config(cfg: TrainConfig, path: Path) -> None:
    write_text(path, yaml.safe_dump(config_to_dict(cfg), sort_keys=False))
