"""The env's parameters from dataclasses, dicts, room YAMLs or None (defaults), checked before anything is built
(``parse_env_params``): the engine (``batched``) and the Gymnasium face (``approach``) both read them."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, NamedTuple

from ...core.layouts import GROUP_MODELS, GroupModel
from ...core.reward import RewardWeights
from ...core.task import TaskParams
from ...params import ConfigError, RobotParams, SocialParams, WorldParams, from_dict, load_yaml
from ..rooms.obstacles import box_rows
from ..rooms.rooms import FurnitureParams, Room, read_obstacles
from ..rooms.scenarios import ScenarioMix

# ``WorldParams`` fields the scenario sets (``scenarios``). Given to the env they are refused, never honoured
# (``World.reset`` alone reads them): a dict names them, so any value is refused; an instance cannot tell a value
# given from its default, so a value other than the default is refused; a room YAML's ``world`` section is a dict.
GROUP_FIELDS = ("n_humans", "formation")


def check_group_fields(world: Any, where: str = "") -> None:
    """Raise if ``world`` (a ``WorldParams``, a dict or None) sets the group (``GROUP_FIELDS``); ``where`` prefixes
    the message (a room YAML's path)."""
    if isinstance(world, dict):
        given = {k: world[k] for k in GROUP_FIELDS if k in world}
    elif isinstance(world, WorldParams):
        default = WorldParams()
        given = {k: getattr(world, k) for k in GROUP_FIELDS if getattr(world, k) != getattr(default, k)}
    else:
        return
    if given:
        k = sorted(given)[0]
        raise ConfigError(f"{where}world.{k} = {given[k]!r}: the scenario sets the group (e.g. scenario "
                          f"'circular-4' for four members in a circle); remove world.{k}")


def _params(cls: type, value: Any, name: str) -> Any:
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        return from_dict(cls, value, name)
    raise ConfigError(f"{name}: expected a {cls.__name__} or a mapping, got {type(value).__name__}")


class EnvParams(NamedTuple):
    """The env's parameters, checked (``parse_env_params``)."""

    scenario: ScenarioMix
    world: WorldParams
    robot: RobotParams
    social: SocialParams
    reward: RewardWeights
    task: TaskParams
    groups: GroupModel
    furniture: FurnitureParams
    map_rooms: tuple[Room, ...]  # the room YAMLs' rooms with their obstacles (rooms ``@map``; one drawn per episode)


def parse_env_params(scenario: str, world: Any, robot: Any, social: Any, reward: Any, task: Any,
                     groups: Any = None, groups_yaml: str | None = None, room_yaml: str | list[str] | None = None,
                     furniture: Any = None) -> EnvParams:
    """The env's parameters from dataclasses, dicts or None (defaults), checked: the room must hold the largest
    group the scenario may spawn, and the group data must hold every size it may spawn. One ``room_yaml``: its
    ``world`` section overlays ``world`` (explicit values win) and its ``obstacles`` make the map room, the
    scenario's room by default. Several (a list, for training in several rooms of a building): each is a map
    room of its own size, one drawn per episode, and the empty room keeps ``world``'s size."""
    check_group_fields(world)
    paths = [] if room_yaml is None else [room_yaml] if isinstance(room_yaml, str | Path) else list(room_yaml)
    if not paths and room_yaml is not None:
        raise ConfigError("room_yaml = []: expected a room YAML or a list of them")
    rooms, obstacles = [], None
    for k, path in enumerate(paths):
        if not isinstance(path, str | Path):
            raise ConfigError(f"room_yaml[{k}] = {path!r}: expected the path of a room YAML (tools/import_map.py)")
        data = load_yaml(path)
        room_world = merged(world if len(paths) == 1 else None, "world", str(path), data, "world")
        check_group_fields(data["world"], f"{path}: ")
        if len(paths) == 1:
            world = room_world
        obstacles = read_obstacles(path, data)
        if obstacles is None and len(paths) > 1:
            raise ConfigError(f"{path}: a room of several (room_yaml list) needs an 'obstacles:' section")
        rooms.append((_params(WorldParams, room_world, "world").room_size, obstacles, str(path)))
    mix = ScenarioMix(scenario, "map" if obstacles is not None else "empty")
    if "map" in mix.rooms and obstacles is None:
        raise ConfigError(f"scenario {scenario!r}: room 'map' needs a room YAML with obstacles (--room-yaml, "
                          + (f"{room_yaml} has no 'obstacles:' section)" if room_yaml else "none given)"))
    world_p, social_p = _params(WorldParams, world, "world"), _params(SocialParams, social, "social")
    furniture_p = _params(FurnitureParams, furniture, "furniture")
    biggest = max(max(sc.sizes) for sc in mix.members)
    if "empty" in mix.rooms:  # a map room is checked by spawning in it (``BatchedApproach._check_map_room``)
        try:
            world_p.check_fits(social_p)
            WorldParams(**{**world_p.__dict__, "n_humans": biggest}).check_fits(social_p)
        except ConfigError as exc:  # a room YAML's size: name the file
            raise (ConfigError(f"{paths[0]}: {exc}") if len(paths) == 1 else exc) from None
    if "furnished" in mix.rooms:
        smallest = (furniture_p.size_min, furniture_p.size_min)
        try:
            WorldParams(**{**world_p.__dict__, "room_size": smallest, "n_humans": biggest}).check_fits(social_p)
        except ConfigError as exc:
            raise ConfigError(f"furniture.size_min = {furniture_p.size_min}: too small for the scenario's groups "
                              f"({exc})") from None
    if isinstance(groups, GroupModel):
        model = groups if groups_yaml is None else dataclasses.replace(groups, data_path=str(groups_yaml))
    elif groups is None or isinstance(groups, str):
        model = GroupModel(groups or "calibrated", None if groups_yaml is None else str(groups_yaml))
    else:
        raise ConfigError(f"groups = {groups!r}: expected one of {GROUP_MODELS}")
    model.check_sizes({n for sc in mix.members for n in sc.sizes}, {f for sc in mix.members for f in sc.formations})
    map_rooms = tuple(Room(size, box_rows(boxes), path) for size, boxes, path in rooms
                      if boxes is not None and "map" in mix.rooms)
    return EnvParams(mix, world_p, _params(RobotParams, robot, "robot"), social_p,
                     _params(RewardWeights, reward, "reward"), _params(TaskParams, task, "task"), model, furniture_p,
                     map_rooms)


def merged(given: Any, key: str, path: str, data: dict[str, Any], section: str | None = None) -> dict[str, Any]:
    """The fields of a calibration YAML's mapping ``data`` (its ``section``) under the ``key`` parameters ``given``
    (a dataclass, a dict or None; explicit values win); a bad value names the file."""
    if section is not None:
        if section not in data or not isinstance(data[section], dict):
            raise ConfigError(f"{path}: expected a '{section}:' mapping (as tools/import_map.py writes)")
        data = data[section]
    cls = {"robot": RobotParams, "social": SocialParams, "world": WorldParams}[key]
    try:  # checked here so that a bad value names the file it came from
        from_dict(cls, data, key)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    given = given or {}
    given = dataclasses.asdict(given) if dataclasses.is_dataclass(given) else dict(given)
    return {**data, **given}
