"""Frozen parameter dataclasses shared by the env, deploy and calibration: defaults are defined once here.

Every field cites its source: the paper (shared/paper/ssbl.tex), the original Unity code and the real Pepper
(shared/reference/peppersocial.md, "ref"), or a choice of ours justified in a comment.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any, TypeVar

import yaml

from .errors import UserError

T = TypeVar("T")


class ConfigError(UserError):
    """A configuration value or file is invalid; the message names the field and what was expected."""


class CalibrationError(ConfigError):
    """Bad calibration input (a file, a field, too few usable samples); the message names the file."""


def _check(cond: bool, owner: str, field: str, value: Any, expected: str) -> None:
    if not cond:
        raise ConfigError(f"{owner}.{field} = {plain(value)!r}: expected {expected}")


def plain(value: Any) -> Any:
    """numpy scalars and arrays as Python numbers and lists, so messages read ``0.3``, not ``np.float64(0.3)``."""
    return value.tolist() if hasattr(value, "tolist") and hasattr(value, "dtype") else value


def _positive(owner: str, obj: Any, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        _check(isinstance(v, int | float) and math.isfinite(v) and v > 0, owner, n, v, "a finite number > 0")


def _nonneg(owner: str, obj: Any, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        _check(isinstance(v, int | float) and math.isfinite(v) and v >= 0, owner, n, v, "a finite number >= 0")


def from_dict(cls: type[T], data: dict[str, Any] | None, where: str = "") -> T:
    """Build ``cls`` from a plain dict, rejecting unknown keys by name (nested dataclasses are recursed)."""
    data = dict(data or {})
    names = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(names))
    label = where or cls.__name__
    if unknown:
        raise ConfigError(f"{label}: unknown key(s) {unknown}; allowed: {sorted(names)}")
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        field = names[key]
        factory = field.default_factory
        if factory is not dataclasses.MISSING and dataclasses.is_dataclass(factory) and isinstance(value, dict):
            kwargs[key] = from_dict(factory, value, f"{label}.{key}")
        elif isinstance(field.default, tuple) and isinstance(value, list):
            kwargs[key] = tuple(value)
        else:
            kwargs[key] = value
    return cls(**kwargs)


class _Loader(yaml.SafeLoader):
    """YAML 1.1's safe loader, reading ``3e-5`` (no dot) as a float as YAML 1.2 and JSON do: PyYAML keeps it a
    string, and a user's ``learning_rate: 3e-5`` failed validation."""


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9]+(?:\.[0-9]*)?[eE][-+]?[0-9]+$"),
                              list("-+0123456789"))


def parse_yaml(text: str) -> Any:
    """YAML text as Python data (``yaml.safe_load``, with ``3e-5`` a float; ``_Loader``)."""
    return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; errors name the file."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path}: is a directory, expected a YAML file")
    if not path.is_file():
        raise ConfigError(f"{path}: file not found")
    try:
        data = parse_yaml(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not UTF-8 text, expected a YAML file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read it ({exc.strerror})") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a YAML mapping at the top level, got {type(data).__name__}")
    return data


@dataclasses.dataclass(frozen=True)
class RobotParams:
    """Pepper's holonomic base and top camera."""

    max_speed: float = 0.35  # m/s, NAOqi default (hardware max 0.55), ref "Real Pepper"
    max_yaw_rate: float = 1.0  # rad/s, NAOqi default (max 2.0), ref
    max_accel: float = 0.3  # m/s^2, NAOqi default (0.1-0.55), ref
    max_yaw_accel: float = 0.75  # rad/s^2, NAOqi default (max 3.0), ref
    latency_s: float = 0.0  # command latency; identified from logs (calib), 0 = ideal
    time_constant_s: float = 0.0  # first-order velocity lag; identified from logs (calib), 0 = none
    length: float = 0.48  # base footprint x (m), ref
    width: float = 0.43  # base footprint y (m), ref
    height: float = 1.21  # m, ref
    camera_height: float = 1.15  # CameraTop optical centre above the floor (m), ref
    camera_forward: float = 0.05  # ahead of the base centre (m), ref
    camera_pitch_deg: float = 0.0  # downward tilt of the optical axis; calib can set it
    camera_hfov_deg: float = 56.3  # OV5640, ref
    camera_vfov_deg: float = 43.7  # ref

    def __post_init__(self) -> None:
        _positive("robot", self, "max_speed", "max_yaw_rate", "max_accel", "max_yaw_accel", "length", "width",
                  "height", "camera_height", "camera_hfov_deg", "camera_vfov_deg")
        _nonneg("robot", self, "latency_s", "time_constant_s")
        _check(self.max_speed <= 0.55, "robot", "max_speed", self.max_speed, "<= 0.55 m/s (Pepper's hardware max)")
        _check(self.camera_hfov_deg < 180, "robot", "camera_hfov_deg", self.camera_hfov_deg, "< 180")
        _check(self.camera_vfov_deg < 180, "robot", "camera_vfov_deg", self.camera_vfov_deg, "< 180")

    @property
    def radius(self) -> float:
        """Body radius used for clearances (m): mean of the footprint half-extents, 0.23 m by default."""
        return 0.25 * (self.length + self.width)

    @property
    def reach(self) -> float:
        """Circumscribed radius of the footprint (m), 0.32 m by default: how far a corner reaches."""
        return 0.5 * math.hypot(self.length, self.width)


@dataclasses.dataclass(frozen=True)
class SocialParams:
    """Social force field model (paper III-C, eqs. 8-10) and the humans' dynamics (ref "Social force field")."""

    personal_radius: float = 1.2  # d_p, repulsion zone (ref scene value; Hall personal 0.45-1.2)
    social_radius: float = 5.0  # equality zone (ref scene value)
    public_radius: float = 8.0  # cohesion zone (ref scene value)
    ospace_radius: float = 1.0  # s, o-space radius for a 2-member group (ref)
    min_member_gap: float = 1.25  # m centre-to-centre between neighbours on the o-space circle; sets the
    #                                radius of larger groups (just over d_p so members feel no repulsion)
    weight_cohesion: float = 2.0  # ref: F = 2 n(F_c) + n(F_e) + n(F_r)
    weight_equality: float = 1.0
    weight_repulsion: float = 1.0
    force_newton: float = 30.0  # ref: normalize(F) * 30 N
    mass: float = 1.0  # kg, ref
    drag: float = 10.0  # 1/s linear drag, ref
    saturation: float = 0.3  # |F| below which forces scale linearly instead of being normalised (ours:
    #                           the ref's hard normalisation chatters at equilibrium; it used a 0.1 m dead band)
    equality_deadband: float = 0.1  # ref: equality acts only while | |p-o| - R_o | > 0.1
    human_radius: float = 0.28  # capsule radius, ref
    max_speed: float = 1.0  # m/s cap on members' repositioning (ours: a brisk step, below walking 1.3 m/s)
    max_turn_rate: float = 1.5  # rad/s for members turning to face the o-space (ours)
    join_margin: float = 1.2  # a robot within s + join_margin of the o-space centre counts as joining (ours)
    fov_half_angle_deg: float = 100.0  # human horizontal field of view half-angle (~200 deg in total)

    def __post_init__(self) -> None:
        _positive("social", self, "personal_radius", "social_radius", "public_radius", "ospace_radius",
                  "min_member_gap", "force_newton", "mass", "drag", "saturation", "human_radius", "max_speed",
                  "max_turn_rate", "join_margin", "fov_half_angle_deg")
        _nonneg("social", self, "weight_cohesion", "weight_equality", "weight_repulsion", "equality_deadband")
        _check(self.personal_radius < self.social_radius <= self.public_radius, "social", "social_radius",
               self.social_radius, f"personal_radius ({self.personal_radius}) < social_radius <= public_radius "
               f"({self.public_radius})")

    def ospace_radius_for(self, n: int) -> float:
        """O-space radius for ``n`` participants: ref's 1.0 m, grown so neighbours keep ``min_member_gap``."""
        if n < 2:
            return self.ospace_radius
        return max(self.ospace_radius, self.min_member_gap / (2.0 * math.sin(math.pi / n)))


FORMATIONS = ("vis_a_vis", "l_shape", "side_by_side", "circular")
APPEARANCES = ("proxy", "body")


@dataclasses.dataclass(frozen=True)
class HumansLook:
    """How the simulator draws the members (the engine's shapes are the same either way)."""

    # "proxy": boxes in the colour detector's colours (cheap to render: training, the figures); "body": people
    # made from a body model (``urdf/bodies``) that a person detector (MoveNet) finds, about 2x the frame time
    appearance: str = "proxy"

    def __post_init__(self) -> None:
        _check(self.appearance in APPEARANCES, "humans", "appearance", self.appearance, f"one of {APPEARANCES}")


@dataclasses.dataclass(frozen=True)
class WorldParams:
    """The room, the group and the spawn rules."""

    room_size: tuple[float, float] = (10.0, 10.0)  # m (ref arena 20 m; ours: a lab room the real robot fits)
    wall_thickness: float = 0.1
    wall_height: float = 1.0
    dt: float = 0.1  # control period (s); 10 Hz matches the deploy loop (ref physics 1/60 s)
    n_humans: int = 2  # ref: 2 simulated humans. These two are ``World.reset``'s defaults only: the env's scenario
    formation: str = "vis_a_vis"  # sets its group and refuses them (``env.engine.env_params.GROUP_FIELDS``)
    robot_spawn_min: float = 2.5  # robot start distance from the group centre (m): outside the c-space ...
    robot_spawn_max: float = 5.5  # ... and close enough for a 30 s episode at 0.35 m/s (ours)
    wall_margin: float = 0.6  # keep bodies this far from the walls at spawn (m)
    humans: HumansLook = dataclasses.field(default_factory=HumansLook)  # how the members are drawn

    def __post_init__(self) -> None:
        _check(isinstance(self.humans, HumansLook), "world", "humans", self.humans,
               "a mapping such as {appearance: body}")
        _check(isinstance(self.room_size, tuple) and len(self.room_size) == 2, "world", "room_size",
               self.room_size, "two numbers (x, y) in metres")
        for v in self.room_size:
            _check(isinstance(v, int | float) and 3.0 <= v <= 100.0, "world", "room_size", self.room_size,
                   "each side in [3, 100] m")
        _positive("world", self, "wall_thickness", "wall_height", "dt", "robot_spawn_min", "robot_spawn_max")
        _nonneg("world", self, "wall_margin")
        _check(isinstance(self.n_humans, int) and 2 <= self.n_humans <= 5, "world", "n_humans", self.n_humans,
               "an integer in [2, 5]")
        _check(self.formation in FORMATIONS, "world", "formation", self.formation, f"one of {FORMATIONS}")
        _check(self.robot_spawn_min < self.robot_spawn_max, "world", "robot_spawn_max", self.robot_spawn_max,
               f"> robot_spawn_min ({self.robot_spawn_min})")
        _check(self.dt <= 0.5, "world", "dt", self.dt, "<= 0.5 s")

    def check_fits(self, social: SocialParams) -> None:
        """Raise if the room cannot hold the group plus the robot's spawn annulus."""
        r = social.ospace_radius_for(self.n_humans + 1) + social.human_radius
        need = 2 * (r + self.wall_margin) + 2 * self.robot_spawn_min * 0.5
        smallest = min(self.room_size)
        _check(smallest >= need, "world", "room_size", self.room_size,
               f"each side >= {need:.2f} m for a group of {self.n_humans} (o-space {r:.2f} m) and a robot "
               f"spawned >= {self.robot_spawn_min} m away")
