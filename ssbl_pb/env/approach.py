"""The approaching task as a Gymnasium env (the core, with the Vector observation).

``gymnasium.make("ssbl_pb/ApproachGroup-v0", obs_mode=..., scenario=...)`` builds it (see ``make_env``);
camera observation modes are wrappers of this one env (``wrappers``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np

from ..errors import UserError
from ..params import ConfigError, RobotParams, SocialParams, WorldParams, from_dict
from . import observation as ob
from .layouts import GROUP_MODELS, GroupModel, slot_keep
from .reward import TERMS, RewardWeights, proximity_cost, reward_terms, route_distance, slot_potential, total_reward
from .scenarios import ScenarioMix
from .task import TaskParams
from .world import World


def _params(cls: type, value: Any, name: str) -> Any:
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        return from_dict(cls, value, name)
    raise TypeError(f"{name}: expected a {cls.__name__} or a dict, got {type(value).__name__}")


def parse_env_params(scenario: str, world: Any, robot: Any, social: Any, reward: Any, task: Any,
                     groups: Any = None, groups_yaml: str | None = None
                     ) -> tuple[ScenarioMix, WorldParams, RobotParams, SocialParams, RewardWeights, TaskParams,
                                GroupModel]:
    """The env's parameters from dataclasses, dicts or None (defaults), checked: the room must hold the largest
    group the scenario may spawn, and the group data must hold every size it may spawn."""
    mix = ScenarioMix(scenario)
    world_p, social_p = _params(WorldParams, world, "world"), _params(SocialParams, social, "social")
    world_p.check_fits(social_p)
    biggest = max(max(sc.sizes) for sc in mix.members)
    WorldParams(**{**world_p.__dict__, "n_humans": biggest}).check_fits(social_p)
    if isinstance(groups, GroupModel):
        model = groups if groups_yaml is None else dataclasses.replace(groups, data_path=str(groups_yaml))
    elif groups is None or isinstance(groups, str):
        model = GroupModel(groups or "calibrated", None if groups_yaml is None else str(groups_yaml))
    else:
        raise ConfigError(f"groups = {groups!r}: expected one of {GROUP_MODELS}")
    model.check_sizes({n for sc in mix.members for n in sc.sizes}, {f for sc in mix.members for f in sc.formations})
    return (mix, world_p, _params(RobotParams, robot, "robot"), social_p, _params(RewardWeights, reward, "reward"),
            _params(TaskParams, task, "task"), model)


class ApproachGroupEnv(gym.Env):
    """Pepper approaches a conversation group and joins it at the free slot."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str = "default",
        world: WorldParams | dict | None = None,
        robot: RobotParams | dict | None = None,
        social: SocialParams | dict | None = None,
        reward: RewardWeights | dict | None = None,
        task: TaskParams | dict | None = None,
        render_mode: str | None = None,
        render_width: int = 480,
        record: bool = False,
        groups: str | GroupModel | None = None,
        groups_yaml: str | None = None,
    ) -> None:
        """``record`` keeps every step's state in ``trajectory`` (metrics, plots; on when rendering).
        ``groups``: where members stand, ``"calibrated"`` (default: real groups' size and irregularity) or
        ``"paper"`` (the original's 1.0 m circle); ``groups_yaml``: the real-group data (default: shipped)."""
        self.scenario, self.world_params, self.robot_params, self.social, self.weights, self.task, self.groups = \
            parse_env_params(scenario, world, robot, social, reward, task, groups, groups_yaml)
        if render_mode not in (None, "rgb_array"):
            raise UserError(f"render_mode {render_mode!r}: expected None or 'rgb_array'")
        self.render_mode = render_mode
        self.render_width = render_width
        self.record = record or render_mode is not None
        keep = slot_keep(self.social, self.robot_params.reach, self.task.intimate_zone, self.task.route_margin)
        self.world = World(self.world_params, self.robot_params, self.social, self.groups, keep)
        n_act = 3 if self.task.turn else 2
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(n_act,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-ob.OBS_LIMIT, ob.OBS_LIMIT, shape=(ob.OBS_SIZE,),
                                                dtype=np.float32)
        self.dt = self.world_params.dt
        self._steps = 0
        self._prev_accel = np.zeros(2)
        self._clearance = np.zeros(0)
        self._sums: dict[str, float] = {}
        self._slot = np.zeros(2)
        self._potential = 0.0
        self.trajectory: list[dict[str, Any]] = []
        self._top_cam = None

    def set_reward_weights(self, **changes: float) -> None:
        """Change reward weights between episodes (training schedules); unknown names raise."""
        self.weights = from_dict(RewardWeights, {**dataclasses.asdict(self.weights), **changes}, "reward")

    # -- helpers ------------------------------------------------------------------------------------------
    def _walls(self) -> np.ndarray:
        sx, sy = self.world_params.room_size
        x, y = self.world.robot_pose[:2]
        return np.array([sx / 2 - x, x + sx / 2, sy / 2 - y, y + sy / 2])

    def slot(self) -> np.ndarray:
        """The free slot now (world frame, metres; updated once per step)."""
        return self._slot

    def _obs(self) -> np.ndarray:
        w, g = self.world, self.world.group
        return ob.vector_observation(w.robot_pose, w.base.vel, g.pos, g.vel, g.centre, g.radius, self._slot,
                                     self._walls(), self.robot_params.max_speed, self.robot_params.max_yaw_rate,
                                     w.robot_pose[2] if self.task.turn else None)

    def _keep_out(self, margin: float) -> float:
        """Radius around the conversation centre a route to the slot keeps out of: the footprint's corners, not
        its mean radius, must stay out of the intimate zone (plus ``margin``)."""
        return (self.world.group.radius + self.social.human_radius + self.robot_params.reach
                + self.task.intimate_zone + margin)

    def _route(self, xy: np.ndarray) -> float:
        """Distance to the free slot around the group (``reward.route_distance``)."""
        return route_distance(xy, self._slot, self.world.group.centre, self._keep_out(self.task.route_margin))

    def heading_error(self) -> float:
        """Angle (rad) from the robot's heading to the conversation centre."""
        (cx, cy), (x, y, yaw) = self.world.group.centre.tolist(), self.world.robot_pose[:3].tolist()
        return math.remainder(math.atan2(cy - y, cx - x) - yaw, 2.0 * math.pi)

    def _snapshot(self) -> dict[str, Any]:
        g = self.world.group
        return {"t": self.world.t, "robot": self.world.robot_pose.copy(), "robot_vel": self.world.base.vel.copy(),
                "members": g.pos.copy(), "members_yaw": g.yaw.copy(), "centre": g.centre.copy(),
                "radius": g.radius, "slot": self._slot.copy(), "clearance": self.world.human_clearance(),
                "wall": float(self.world.wall_clearance().min()),  # the footprint's clearance to the nearest wall
                # the SFFM's repulsion on the robot and on the members (metrics' social work)
                "social_force": float(np.hypot(*g.robot_repulsion) + np.hypot(*g.repulsion.T).sum())}

    # -- Gymnasium API ------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        n, formation, start = self.scenario.sample(self.np_random)
        self.world.reset(self.np_random, n_humans=n, formation=formation, start=start)
        self._steps = 0
        self._prev_accel = np.zeros(2)
        self._sums = {k: 0.0 for k in (*TERMS, "reward")}
        self._slot = self.world.group.free_slot(self.world.robot_pose[:2])
        self._potential = slot_potential(self._route(self.world.robot_pose[:2]), 0.0)
        self._clearance = self.world.human_clearance()
        self.trajectory = [{**self._snapshot(), "keep_out": self._keep_out(0.0)}] if self.record else []
        self._top_cam = None
        info = {"n_humans": n, "formation": formation, "start": start}
        return self._obs(), info

    def command(self, action: np.ndarray) -> np.ndarray:
        """Body-frame base command (forward, left, turn) for a normalised action.

        The action is (toward the centre, to the left of that) in the approach frame (``observation``), or
        (forward, left, turn) in the body frame when the policy steers (``TaskParams.turn``).
        """
        a = [min(max(v, -1.0), 1.0) for v in np.asarray(action, dtype=float).ravel().tolist()]
        rp = self.robot_params
        if self.task.turn:
            return np.array([a[0] * rp.max_speed, a[1] * rp.max_speed, a[2] * rp.max_yaw_rate])
        e = self.heading_error()
        turn = min(max(self.task.heading_gain * e, -rp.max_yaw_rate), rp.max_yaw_rate)
        c, s = math.cos(e), math.sin(e)  # approach frame -> body frame
        return np.array([(c * a[0] - s * a[1]) * rp.max_speed, (s * a[0] + c * a[1]) * rp.max_speed, turn])

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        w, g = self.world, self.world.group
        a = np.asarray(action, dtype=float).reshape(self.action_space.shape)  # ``command`` clips it
        # stepping replaces these arrays (never writes into them), so the old ones are the "before" states
        robot_before, members_before, vel_before = w.base.pose[:2], g.pos, w.base.vel[:2]
        potential_before = self._potential  # the state's potential, computed at the end of the previous step
        w.step(self.command(a))
        self._steps += 1
        xy = w.robot_pose[:2]
        self._slot = g.free_slot(xy)
        slot_after = math.dist(self._slot.tolist(), xy.tolist())
        clearance = w.human_clearance()
        collided = w.in_contact(clearance)
        violation = collided or bool(clearance.min() < self.task.intimate_zone)
        speed = math.hypot(*w.base.vel[:2].tolist())
        success = (not violation and slot_after < self.task.slot_tolerance and speed < self.task.stop_speed
                   and abs(self.heading_error()) < math.radians(self.task.heading_tolerance_deg))
        accel = (w.base.vel[:2] - vel_before) / self.dt
        self._potential = slot_potential(self._route(w.robot_pose[:2]), speed)
        proximity = proximity_cost(self._clearance, clearance, self.task.intimate_zone, self.task.proximity_band)
        self._clearance = clearance
        terms = reward_terms(g.robot_force, w.robot_pose[:2] - robot_before, g.force, g.pos - members_before,
                             g.repulsion, self.dt, accel, self._prev_accel, potential_before, self._potential,
                             success, violation, proximity, (self.task.max_steps - self._steps) * self.dt)
        r = total_reward(terms, self.weights)
        self._prev_accel = accel
        for k, v in terms.items():
            self._sums[k] += v
        self._sums["reward"] += r
        if self.record:
            self.trajectory.append(self._snapshot())
        terminated = success or violation
        truncated = not terminated and self._steps >= self.task.max_steps
        info: dict[str, Any] = {"terms": terms, "success": success, "collision": collided,
                                "violation": violation, "slot_distance": slot_after}
        if terminated or truncated:
            info["episode_terms"] = dict(self._sums)
            info["is_success"] = success  # SB3's convention for success-rate logging
        return self._obs(), r, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        from .drawing import draw_overlay

        if self._top_cam is None:  # framed on the group and the robot's start, fixed for the episode
            g, start = self.world.group, self.trajectory[0]["robot"][:2]
            mid = 0.5 * (g.centre0 + start)
            size = max(6.0, float(np.hypot(*(start - g.centre0))) + 2 * g.joined_radius + 2.0)
            self._top_cam = self.world.top_down_camera(self.render_width, tuple(mid), size)
        img = self.world.render_top_down(self._top_cam)
        return draw_overlay(img, self._top_cam, self.trajectory, self.social, self.task)

    def close(self) -> None:
        self.world.close()


def _merge_yaml(kwargs: dict[str, Any], key: str, path: str | None, section: str | None = None) -> None:
    """Overlay the fields of a calibration YAML onto the ``key`` parameters (explicit values still win)."""
    if path is None:
        return
    from ..params import ConfigError, load_yaml

    data = load_yaml(path)
    if section is not None:
        if section not in data or not isinstance(data[section], dict):
            raise ConfigError(f"{path}: expected a '{section}:' mapping (as tools/import_map.py writes)")
        data = data[section]
    given = kwargs.get(key) or {}
    given = dataclasses.asdict(given) if dataclasses.is_dataclass(given) else dict(given)
    kwargs[key] = {**data, **given}


def make_env(obs_mode: str = "vector", camera_width: int = 84, camera_height: int = 84,
             camera_yaml: str | None = None, robot_yaml: str | None = None, social_yaml: str | None = None,
             room_yaml: str | None = None, **kwargs: Any) -> gym.Env:
    """Entry point of ``ssbl_pb/ApproachGroup-v0``: the core env wrapped for ``obs_mode``.

    ``camera_yaml`` (a ROS camera_info YAML from ``tools/calibrate_camera.py``) makes the first-person camera
    match a calibrated camera: its intrinsics set the projection, its field of view and (when calibrated) its
    height, pitch and forward offset set ``RobotParams``. ``robot_yaml`` (``tools/identify_dynamics.py``),
    ``social_yaml`` (``tools/calibrate_humans.py``) and ``room_yaml`` (``tools/import_map.py``, its ``world``
    section) overlay calibrated values on the defaults. ``groups_yaml`` (``tools/calibrate_groups.py``) replaces
    the real-group data the groups are drawn from (``groups="calibrated"``, the default, and scenario ``real``).
    """
    from .wrappers import OBS_MODES, wrap_obs_mode

    if obs_mode not in OBS_MODES:
        raise UserError(f"obs_mode {obs_mode!r}: expected one of {OBS_MODES}")
    kwargs, projection = core_kwargs(camera_width, camera_height, camera_yaml, robot_yaml, social_yaml, room_yaml,
                                     **kwargs)
    return wrap_obs_mode(ApproachGroupEnv(**kwargs), obs_mode, camera_width, camera_height, projection)


def core_kwargs(camera_width: int = 84, camera_height: int = 84, camera_yaml: str | None = None,
                robot_yaml: str | None = None, social_yaml: str | None = None, room_yaml: str | None = None,
                **kwargs: Any) -> tuple[dict[str, Any], list[float] | None]:
    """``make_env``'s calibration files folded into the core env's keyword arguments, and the calibrated
    camera's projection (None without ``camera_yaml``)."""
    _merge_yaml(kwargs, "robot", robot_yaml)
    _merge_yaml(kwargs, "social", social_yaml)
    _merge_yaml(kwargs, "world", room_yaml, "world")
    projection = None
    if camera_yaml is not None:
        from ..perception.camera import PinholeCamera, sim_projection_from_yaml

        cam = PinholeCamera.from_yaml(camera_yaml)
        robot = kwargs.get("robot") or {}
        robot = dataclasses.asdict(robot) if isinstance(robot, RobotParams) else dict(robot)
        kwargs["robot"] = {**robot, **cam.robot_overrides()}
        projection = sim_projection_from_yaml(camera_yaml, camera_width, camera_height)
    return kwargs, projection
