"""The approaching task's state for N copies and its step: the one engine behind every env.

``BatchedApproach`` keeps N episodes in arrays (the base's in ``base.BaseArrays``, the groups' in
``humans.GroupArrays``, padded to ``MAX_HUMANS`` members, the task's here) and advances all of them with one call
of ``kernels.step``. Training runs it with N copies (``training.vec_env.BatchedVecEnv``); the Gymnasium env
``ApproachGroupEnv`` is a batch of one with a PyBullet scene for rendering; so a copy seeded like a single env
plays the same episode, by construction. Resets spawn in Python (``world.spawn_layout``, ``GroupArrays.spawn``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from ..errors import UserError
from ..params import RobotParams, SocialParams, WorldParams, from_dict
from . import kernels
from . import observation as ob
from .approach import parse_env_params
from .base import BaseArrays, BaseParams, wall_clearance
from .humans import KEEP, RADIUS, GroupArrays, free_slot, sffm_params
from .layouts import GroupModel, slot_keep
from .reward import TERMS, RewardWeights, weight_vector
from .scenarios import apply_reset_options
from .task import TaskParams
from .world import MAX_HUMANS, spawn_layout


class BatchedApproach:
    """N copies of the approaching task; ``reset(i)`` starts copy i's next episode, ``step`` advances all."""

    def __init__(self, num: int, scenario: str = "default", world: WorldParams | dict | None = None,
                 robot: RobotParams | dict | None = None, social: SocialParams | dict | None = None,
                 reward: RewardWeights | dict | None = None, task: TaskParams | dict | None = None,
                 groups: str | GroupModel | None = None, groups_yaml: str | None = None) -> None:
        if not isinstance(num, int) or num < 1:
            raise UserError(f"number of copies {num!r}: expected an integer >= 1")
        self.num = num
        self.kwargs = {"scenario": scenario, "world": world, "robot": robot, "social": social, "reward": reward,
                       "task": task, "groups": groups, "groups_yaml": groups_yaml}  # ``like`` builds more
        self.scenario, self.world_params, self.robot_params, self.social, self.weights, self.task, self.groups = \
            parse_env_params(scenario, world, robot, social, reward, task, groups, groups_yaml)
        self.dt = self.world_params.dt
        self.n_act = 3 if self.task.turn else 2
        self.keep = slot_keep(self.social, self.robot_params.reach, self.task.intimate_zone,
                              self.task.route_margin)  # the robot's place from members (``layouts.slot_keep``)
        self._bparams = BaseParams.of(self.robot_params, self.dt)
        self._bp = np.array(self._bparams, dtype=float)
        self._sp = sffm_params(self.social, self.dt)
        self._tp = kernels.task_params(self.world_params, self.robot_params, self.social, self.task)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(num)]
        self.bases, self.groups_state = BaseArrays(num, self._bparams), GroupArrays(num)
        m = MAX_HUMANS
        self.steps = np.zeros(num, dtype=np.int64)
        self.prev_accel = np.zeros((num, 2))
        self.clearance = np.zeros((num, m))
        self.slot = np.zeros((num, 2))
        self.potential = np.zeros(num)
        self.sums = np.zeros((num, len(TERMS) + 1))  # episode sums of the terms and of the reward
        self.terms = np.zeros((num, len(TERMS)))  # the last step's terms
        self.rewards = np.zeros(num)
        self.flags = np.zeros((num, 5), dtype=bool)  # kernels.TERMINATED ... COLLISION
        self._obs = np.zeros((num, ob.OBS_SIZE), dtype=np.float32)
        self._all = np.arange(num)

    def like(self, num: int) -> BatchedApproach:
        """A batch of ``num`` copies with this one's parameters (weights as they are now)."""
        return BatchedApproach(num, **{**self.kwargs, "reward": self.weights})

    # -- state, named ------------------------------------------------------------------------------------
    pose = property(lambda self: self.bases.pose)
    vel = property(lambda self: self.bases.vel)
    pos = property(lambda self: self.groups_state.pos)
    count = property(lambda self: self.groups_state.count)
    centre = property(lambda self: self.groups_state.centre)
    radius = property(lambda self: self.groups_state.scalars[:, RADIUS])
    success = property(lambda self: self.flags[:, kernels.SUCCESS])
    violation = property(lambda self: self.flags[:, kernels.VIOLATION])
    collision = property(lambda self: self.flags[:, kernels.COLLISION])

    @property
    def weights(self) -> RewardWeights:
        """The reward weights of every copy; assigning them (a ``RewardWeights`` or a dict) takes effect at once."""
        return self._weights

    @weights.setter
    def weights(self, value: RewardWeights | dict) -> None:
        self._weights = value if isinstance(value, RewardWeights) else from_dict(RewardWeights, value, "reward")
        self._w = weight_vector(self._weights)

    def set_reward_weights(self, **changes: float) -> None:
        """Change reward weights of every copy (training schedules); unknown names raise."""
        self.weights = {**dataclasses.asdict(self.weights), **changes}

    def observations(self, rows: np.ndarray | None = None) -> np.ndarray:
        """The Vector observations (N, OBS_SIZE) of the current states (recomputing ``rows`` only, if given)."""
        g = self.groups_state
        kernels.observations(self._tp, self.pose, self.vel, g.count, g.pos, g.vel, g.centre, g.scalars, self.slot,
                             self._obs, self._all if rows is None else rows)
        return self._obs.copy()

    # -- episodes ---------------------------------------------------------------------------------------
    def seed(self, i: int, seed: int | None) -> None:
        """Seed copy ``i``'s generator as ``ApproachGroupEnv.reset(seed=...)`` seeds the single env's."""
        self.rngs[i] = seeding.np_random(seed)[0]

    def reset(self, i: int, options: dict | None = None) -> dict[str, Any]:
        """Start copy ``i``'s next episode (``reset(options=...)`` as ``ApproachGroupEnv``); returns its info."""
        rng = self.rngs[i]
        n, formation, start = apply_reset_options(self.scenario.sample(rng), options)
        centre, layout, pose = spawn_layout(rng, self.world_params, self.robot_params, self.social, n, formation,
                                            start, self.groups)
        self.bases.reset(i, pose)
        g = self.groups_state
        g.spawn(i, self.social, centre, layout, self.keep, pose[:2])
        self.steps[i], self.prev_accel[i], self.sums[i], self.terms[i], self.flags[i] = 0, 0.0, 0.0, 0.0, False
        self.slot[i] = free_slot(n, g.pos[i], *g.centre[i], g.scalars[i, RADIUS], g.scalars[i, KEEP], *pose[:2],
                                 True)
        self.clearance[i] = 0.0
        kernels.clearances(self._tp, self.pose[i], n, g.pos[i], self.clearance[i])
        self.potential[i] = kernels.potential(self._tp, self.pose[i], self.slot[i], g.centre[i],
                                              g.scalars[i, RADIUS], 0.0)
        return {"n_humans": n, "formation": formation, "start": start}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance every copy by one control period (actions (N, A) in [-1, 1]).

        Returns rewards (N,), terminated (N,) and truncated (N,); ``success``, ``violation``, ``collision`` and
        ``terms`` hold the last step's. Finished copies keep their final state until ``reset(i)``.
        """
        a = np.ascontiguousarray(actions, dtype=np.float64).reshape(self.num, self.n_act)
        b, g = self.bases, self.groups_state
        kernels.step(self._tp, self._bp, self._sp, self._w, a, b.pose, b.vel, b.queue, g.count, g.pos, g.vel, g.yaw,
                     g.centre0, g.centre, g.scalars, g.ring_offset, g.comfort, g.force, g.repulsion, g.robot_force,
                     self.steps, self.prev_accel, self.clearance, self.slot, self.potential, self.sums, self.terms,
                     self.rewards, self.flags)
        return self.rewards.copy(), self.flags[:, kernels.TERMINATED].copy(), self.flags[:, kernels.TRUNCATED].copy()

    def keep_out(self, i: int, margin: float) -> float:
        """Radius around copy ``i``'s conversation centre the shaping's way to the slot keeps out of: the
        footprint's corners, not its mean radius, must stay out of the intimate zone (plus ``margin``)."""
        return (float(self.radius[i]) + self.social.human_radius + self.robot_params.reach + self.task.intimate_zone
                + margin)

    def snapshot(self, i: int, t: float) -> dict[str, Any]:
        """Copy ``i``'s state at time ``t`` as recorded in trajectories (metrics, plots, videos): copies."""
        g, n = self.groups_state, int(self.groups_state.count[i])
        x, y, yaw = (float(v) for v in self.pose[i])
        rp = self.robot_params
        walls = wall_clearance(x, y, yaw, rp.length / 2, rp.width / 2, *self.world_params.room_size)
        return {"t": t, "robot": self.pose[i].copy(), "robot_vel": self.vel[i].copy(), "members": g.pos[i, :n].copy(),
                "members_yaw": g.yaw[i, :n].copy(), "centre": g.centre[i].copy(), "radius": float(self.radius[i]),
                "slot": self.slot[i].copy(), "clearance": self.clearance[i, :n].copy(),
                "wall": float(min(walls)),  # the footprint's clearance to the nearest wall
                # the SFFM's repulsion on the robot and on the members (metrics' social work)
                "social_force": float(np.hypot(*g.robot_force[i, 2:]) + np.hypot(*g.repulsion[i, :n].T).sum())}

    def outcome(self, i: int) -> dict[str, Any]:
        """Copy ``i``'s last step as the env's ``info`` reports it (at an episode's end: ``episode_terms``)."""
        f = self.flags[i]
        info: dict[str, Any] = {"terms": dict(zip(TERMS, self.terms[i].tolist(), strict=True)),
                                "success": bool(f[kernels.SUCCESS]), "collision": bool(f[kernels.COLLISION]),
                                "violation": bool(f[kernels.VIOLATION]),
                                "slot_distance": float(np.hypot(*(self.slot[i] - self.pose[i, :2])))}
        if f[kernels.TERMINATED] or f[kernels.TRUNCATED]:
            info["episode_terms"] = self.episode_terms(i)
            info["is_success"] = info["success"]  # SB3's convention for success-rate logging
        return info

    def episode_terms(self, i: int) -> dict[str, float]:
        """Copy ``i``'s sums of every term and of the reward so far."""
        return dict(zip((*TERMS, "reward"), self.sums[i].tolist(), strict=True))
