"""The approaching task as a Gymnasium env (the core, with the Vector observation).

``gymnasium.make("ssbl_pb/ApproachGroup-v0", obs_mode=..., scenario=...)`` builds it (see ``make_env``);
camera observation modes are wrappers of this one env (``wrappers``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ...core import humans
from ...core import observation as ob
from ...core.layouts import GroupModel
from ...core.reward import RewardWeights
from ...core.task import TaskParams
from ...errors import UserError
from ...params import RobotParams, SocialParams, WorldParams, load_yaml
from ...perception.camera import PinholeCamera, sim_projection_from_yaml
from ..engine import kernels
from ..engine.batched import BatchedApproach
from ..engine.env_params import merged
from ..rooms.rooms import FurnitureParams
from ..view.drawing import draw_overlay
from ..view.world import World
from .wrappers import OBS_MODES, wrap_obs_mode


class ApproachGroupEnv(gym.Env):
    """Pepper approaches a conversation group and joins it at the free slot.

    Observation: the Vector observation (``observation``, 64 floats with the range scan, 40 without). Action:
    (toward the centre, to its left) in [-1, 1] (x max speed), plus a turn with ``TaskParams.turn``. Start: a room
    (empty, furnished or the map's: the scenario's ``@ROOM``), a group of the scenario's size and formation at a
    random free place, the robot 2.5-5.5 m away (``spawn.spawn_layout``). Reward: eq. 15 with our terms
    (``reward``). Ends: success (``task.joined``), a collision (with a member, a wall or an obstacle) or an
    intimate-zone intrusion (terminated), or ``max_steps`` (truncated). Each step's ``info``: ``terms``
    (unweighted reward terms), ``success``, ``collision``, ``obstacle_collision`` (a wall or an obstacle),
    ``violation``, ``slot_distance``; at the end also ``episode_terms`` and ``is_success``.

    The state and its step are a batch of one of the training engine (``batched.BatchedApproach``); ``world`` is
    the PyBullet scene showing that state (rendering, cameras, contact checks), its ``base`` and ``group`` views
    of the batch's arrays.
    """

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
        room_yaml: str | list[str] | None = None,
        furniture: FurnitureParams | dict | None = None,
        scan: bool = True,
        waypoints: bool = False,
        waypoints_near_group: bool = False,
        perception: Any = None,
        member_order: str = "nearest",
    ) -> None:
        """``record`` keeps every step's state in ``trajectory`` (metrics, plots; on when rendering).
        ``groups``: where members stand, ``"calibrated"`` (default: real groups' size and irregularity) or
        ``"paper"`` (the original's 1.0 m circle); ``groups_yaml``: the real-group data (default: shipped).
        ``room_yaml``: a room YAML (``tools/import_map.py``): its room size, and its obstacles for rooms ``@map``
        (the scenario's rooms: ``scenarios``), or a list of them (each ``@map`` episode in one of those rooms,
        drawn at random; for training in several rooms); ``furniture``: how rooms ``@furnished`` are drawn
        (``rooms.FurnitureParams``); ``scan``: the range scan in the observation (False: the 40 entries policies
        trained before it read); ``waypoints``: in rooms with obstacles, the slot's entries show the way around
        them while the slot is out of sight (``planner``; off for policies trained before it);
        ``waypoints_near_group``: right up to the group's keep-out disc (``planner.way_in_for_group``);
        ``perception``: the observation model (``perception.groups.observation_model``; off by default: the true
        state), true or a mapping of ``PerceptionParams``' fields: the policy sees the group as deploy's perception
        would; ``member_order``: the order of the observation's member blocks, ``nearest`` first (default) or by
        ``bearing`` (``core.observation``)."""
        if render_mode not in (None, "rgb_array"):
            raise UserError(f"render_mode {render_mode!r}: expected None or 'rgb_array'")
        if not isinstance(render_width, int) or not 64 <= render_width <= 4096:
            raise UserError(f"render width {render_width!r}: expected an integer in [64, 4096] pixels")
        self.sim = BatchedApproach(1, scenario, world, robot, social, reward, task, groups, groups_yaml, room_yaml,
                                   furniture, scan, waypoints, waypoints_near_group, perception, member_order)
        sim = self.sim
        self.scenario, self.world_params, self.robot_params = sim.scenario, sim.world_params, sim.robot_params
        self.social, self.task, self.groups = sim.social, sim.task, sim.groups
        self.render_mode = render_mode
        self.render_width = render_width
        self.record = record or render_mode is not None
        self.world = World(self.world_params, self.robot_params, self.social, self.groups, sim.keep, sim.rooms[0])
        self.world.attach(sim.bases, sim.groups_state, 0)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(sim.n_act,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-ob.OBS_LIMIT, ob.OBS_LIMIT, shape=(sim.obs_size,),
                                                dtype=np.float32)
        self.dt = self.world_params.dt
        self.trajectory: list[dict[str, Any]] = []
        self._top_cam = None

    @property
    def weights(self) -> RewardWeights:
        return self.sim.weights

    @weights.setter
    def weights(self, value: RewardWeights | dict) -> None:
        self.sim.weights = value

    def set_reward_weights(self, **changes: float) -> None:
        """Change reward weights between episodes (training schedules); unknown names raise."""
        self.sim.set_reward_weights(**changes)

    # -- the state ----------------------------------------------------------------------------------------
    def slot(self) -> np.ndarray:
        """The free slot now (world frame, metres; updated once per step)."""
        return self.sim.slot[0]

    def heading_error(self) -> float:
        """Angle (rad) from the robot's heading to the conversation centre."""
        return kernels.heading_error(self.sim.pose[0], self.sim.centre[0])

    def keep_out(self, margin: float | None = None) -> float:
        """``BatchedApproach.keep_out`` of this env (``margin`` default: the task's route margin)."""
        return self.sim.keep_out(0, self.task.route_margin if margin is None else margin)

    def refresh(self) -> None:
        """Recompute the slot, clearances and shaping potential after the state was moved by hand (tests, a
        simulated robot placed somewhere), as ``reset`` does."""
        sim, g = self.sim, self.sim.groups_state
        n = int(g.count[0])
        sim.slot[0] = humans.free_slot(n, g.pos[0], *g.centre[0], g.scalars[0, humans.RADIUS],
                                       g.scalars[0, humans.KEEP], *sim.pose[0, :2], True)
        kernels.clearances(sim._tp, sim.pose[0], n, g.pos[0], sim.clearance[0])
        speed = float(np.hypot(*sim.vel[0, :2]))
        sim.potential[0] = sim.potential_of(0, speed)
        self.world.invalidate()


    # -- Gymnasium API ------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.sim.rngs[0] = self.np_random  # the env's generator draws the episode
        if seed is not None and self.sim.perceived is not None:  # the observation model's own generator
            self.sim.perceived.seed(0, seed)
        info = self.sim.reset(0, options)
        self.world.set_room(self.sim.rooms[0])
        self.world.t = 0.0
        self.world.invalidate()
        self.trajectory = [{**self.sim.snapshot(0, 0.0), **self.sim.room_info(0), "keep_out": self.keep_out(0.0)}
                           ] if self.record else []
        self._top_cam = None
        return self.observe(), info

    def observe(self) -> np.ndarray:
        """The Vector observation of the current state."""
        return self.sim.observations()[0]

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        rewards, terminated, truncated = self.sim.step(np.asarray(action, dtype=float).reshape(1, -1))
        self.world.t += self.dt
        self.world.invalidate()
        if self.record:
            self.trajectory.append(self.sim.snapshot(0, self.world.t))
        return self.observe(), float(rewards[0]), bool(terminated[0]), bool(truncated[0]), self.sim.outcome(0)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._top_cam is None:  # framed on the group and the robot's start, fixed for the episode
            g, start = self.world.group, self.trajectory[0]["robot"][:2]
            mid = 0.5 * (g.centre0 + start)
            size = max(6.0, float(np.hypot(*(start - g.centre0))) + 2 * g.joined_radius + 2.0)
            self._top_cam = self.world.top_down_camera(self.render_width, tuple(mid), size)
        img = self.world.render_top_down(self._top_cam)
        return draw_overlay(img, self._top_cam, self.trajectory, self.social, self.task)

    def close(self) -> None:
        self.world.close()


def _merge_yaml(kwargs: dict[str, Any], key: str, path: str | None) -> None:
    """Overlay the fields of a calibration YAML onto the ``key`` parameters (explicit values still win)."""
    if path is not None:
        kwargs[key] = merged(kwargs.get(key), key, path, load_yaml(path))


def make_env(obs_mode: str = "vector", camera_width: int = 84, camera_height: int = 84,
             camera_yaml: str | None = None, robot_yaml: str | None = None, social_yaml: str | None = None,
             room_yaml: str | list[str] | None = None, encoder: str | None = None, feature_smoothing: float = 1.0,
             **kwargs: Any) -> gym.Env:
    """Entry point of ``ssbl_pb/ApproachGroup-v0``: the core env wrapped for ``obs_mode``.

    ``encoder`` (a ``tools/train_ae.py`` checkpoint; camera modes only) replaces the images by the frozen
    encoder's features (``env.gymenv.encoded``) and sets the camera's field of view to the one it learned through (a
    ``camera_yaml`` must agree with it within 5 % magnification and then sets it); ``feature_smoothing`` < 1
    low-passes those features over the episode (``env.gymenv.encoded``).

    ``camera_yaml`` (a ROS camera_info YAML from ``tools/calibrate_camera.py``) makes the first-person camera
    match a calibrated camera: its intrinsics set the projection, its field of view and (when calibrated) its
    height, pitch and forward offset set ``RobotParams``. ``robot_yaml`` (``tools/identify_dynamics.py``),
    ``social_yaml`` (``tools/calibrate_humans.py``) and ``room_yaml`` (``tools/import_map.py``, its ``world``
    section) overlay calibrated values on the defaults. ``groups_yaml`` (``tools/calibrate_groups.py``) replaces
    the real-group data the groups are drawn from (``groups="calibrated"``, the default, and scenario ``real``).
    """
    if obs_mode not in OBS_MODES:
        raise UserError(f"obs_mode {obs_mode!r}: expected one of {OBS_MODES}")
    if encoder is not None:  # the camera the encoder learned through
        from .encoded import EncodedObservation, load_encoder, with_encoder_camera  # lazy: loads torch and SB3

        kwargs = with_encoder_camera({**kwargs, "camera_yaml": camera_yaml}, encoder)
        kwargs.pop("camera_yaml")
    kwargs, projection = core_kwargs(camera_width, camera_height, camera_yaml, robot_yaml, social_yaml, room_yaml,
                                     **kwargs)
    env = wrap_obs_mode(ApproachGroupEnv(**kwargs), obs_mode, camera_width, camera_height, projection)
    if encoder is not None:
        env = EncodedObservation(env, load_encoder(encoder, camera_width), feature_smoothing)
    elif feature_smoothing != 1.0:
        raise UserError(f"feature_smoothing {feature_smoothing!r}: filters a frozen encoder's features; give an "
                        "encoder (or leave it at 1)")
    return env


def core_kwargs(camera_width: int = 84, camera_height: int = 84, camera_yaml: str | None = None,
                robot_yaml: str | None = None, social_yaml: str | None = None,
                room_yaml: str | list[str] | None = None, **kwargs: Any) -> tuple[dict[str, Any], list[float] | None]:
    """``make_env``'s calibration files folded into the core env's keyword arguments, and the calibrated
    camera's projection (None without ``camera_yaml``)."""
    _merge_yaml(kwargs, "robot", robot_yaml)
    _merge_yaml(kwargs, "social", social_yaml)
    if room_yaml is not None:  # the core env reads its room size and obstacles (several rooms: a list)
        kwargs["room_yaml"] = (str(room_yaml) if isinstance(room_yaml, str | Path)
                               else [str(r) if isinstance(r, Path) else r for r in room_yaml])
    projection = None
    if camera_yaml is not None:
        cam = PinholeCamera.from_yaml(camera_yaml)
        robot = kwargs.get("robot") or {}
        robot = dataclasses.asdict(robot) if isinstance(robot, RobotParams) else dict(robot)
        kwargs["robot"] = {**robot, **cam.robot_overrides()}
        projection = sim_projection_from_yaml(camera_yaml, camera_width, camera_height)
    return kwargs, projection
