"""N episodes of the approaching task stepped together by compiled kernels (training throughput).

``BatchedApproach`` is ``ApproachGroupEnv`` (Vector observation) for N independent copies, without PyBullet: its
state lives in arrays (groups padded to ``MAX_HUMANS`` members) and ``kernels`` step, observe and shield every
copy in one call each, with the single env's arithmetic. One step of 8 copies costs ~35 us where 8 single envs
cost ~1.5 ms (numpy's fixed cost per call on arrays of 2-6 agents). Resets (rare) spawn through the single env's
own code (``world.spawn_layout``, ``humans.Group``), so a copy seeded like a single env plays the same episode:
``tests/test_batched.py`` steps both with the same actions and compares every state, reward and ending.

The single env stays the reference, used for evaluation, rendering, metrics and deploy; this class serves
training (``training.vec_env.BatchedVecEnv`` wraps it for SB3). Per-step infos carry what training reads
(``is_success`` and ``episode_terms`` at an episode's end), not the single env's per-step ``terms``.
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
from .humans import Group
from .layouts import GroupModel, slot_keep
from .reward import TERMS, RewardWeights, weight_vector
from .scenarios import apply_reset_options
from .task import TaskParams
from .world import MAX_HUMANS, box_circle_distance, spawn_layout


class BatchedApproach:
    """N copies of the approaching task; ``reset(i)`` starts copy i's next episode, ``step`` advances all."""

    def __init__(self, num: int, scenario: str = "default", world: WorldParams | dict | None = None,
                 robot: RobotParams | dict | None = None, social: SocialParams | dict | None = None,
                 reward: RewardWeights | dict | None = None, task: TaskParams | dict | None = None,
                 groups: str | GroupModel | None = None, groups_yaml: str | None = None) -> None:
        if not isinstance(num, int) or num < 1:
            raise UserError(f"number of copies {num!r}: expected an integer >= 1")
        self.num = num
        self.scenario, self.world_params, self.robot_params, self.social, self.weights, self.task, self.groups = \
            parse_env_params(scenario, world, robot, social, reward, task, groups, groups_yaml)
        self.dt = self.world_params.dt
        self.n_act = 3 if self.task.turn else 2
        self._keep = slot_keep(self.social, self.robot_params.reach, self.task.intimate_zone, self.task.route_margin)
        self._p = kernels.pack_params(self.world_params, self.robot_params, self.social, self.task)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(num)]
        m = MAX_HUMANS
        delay = int(self._p[kernels.DELAY_STEPS])
        # the base
        self.pose, self.vel = np.zeros((num, 3)), np.zeros((num, 3))
        self.queue = np.zeros((num, delay + 2, 3))  # latency: [:, 0] is now, as HolonomicBase's deque
        # the group (padded to m members; ``count`` are real)
        self.count = np.full(num, 2, dtype=np.int64)
        self.pos, self.mvel, self.myaw = np.zeros((num, m, 2)), np.zeros((num, m, 2)), np.zeros((num, m))
        self.centre0, self.centre = np.zeros((num, 2)), np.zeros((num, 2))
        self.base_radius, self.joined_radius, self.join_radius = np.ones(num), np.ones(num), np.ones(num)
        self.ring_offset, self.comfort = np.zeros((num, m)), np.zeros((num, m))  # per member (``Group``)
        self.keep, self.shift = np.zeros(num), np.ones(num)  # the slot's distance rule, the centre's shift
        self.radius, self.join_weight = np.ones(num), np.zeros(num)
        self.force, self.repulsion = np.zeros((num, m, 2)), np.zeros((num, m, 2))
        self.robot_force = np.zeros((num, 2))
        # the task
        self.steps = np.zeros(num, dtype=np.int64)
        self.prev_accel = np.zeros((num, 2))
        self.clearance = np.zeros((num, m))
        self.slot = np.zeros((num, 2))
        self.potential = np.zeros(num)
        self.sums = np.zeros((num, len(TERMS) + 1))  # episode sums of the terms and of the reward
        self.rewards = np.zeros(num)
        self.flags = np.zeros((num, 5), dtype=bool)  # terminated, truncated, success, violation, collision
        self._obs = np.zeros((num, ob.OBS_SIZE), dtype=np.float32)
        self._all = np.arange(num)

    @property
    def weights(self) -> RewardWeights:
        """The reward weights of every copy; assigning them (a ``RewardWeights`` or a dict) takes effect at once."""
        return self._weights

    @weights.setter
    def weights(self, value: RewardWeights | dict) -> None:
        self._weights = value if isinstance(value, RewardWeights) else from_dict(RewardWeights, value, "reward")
        self._w = weight_vector(self._weights)

    def set_reward_weights(self, **changes: float) -> None:
        """``ApproachGroupEnv.set_reward_weights`` for every copy."""
        self.weights = {**dataclasses.asdict(self.weights), **changes}

    @property
    def success(self) -> np.ndarray:
        return self.flags[:, 2]

    @property
    def violation(self) -> np.ndarray:
        return self.flags[:, 3]

    @property
    def collision(self) -> np.ndarray:
        return self.flags[:, 4]

    def heading_error(self) -> np.ndarray:
        """Angle (rad) from each robot's heading to its conversation centre."""
        return np.array([kernels._heading_error(self.pose, self.centre, i) for i in range(self.num)])

    def observations(self, rows: np.ndarray | None = None) -> np.ndarray:
        """The Vector observations (N, OBS_SIZE) of the current states (recomputing ``rows`` only, if given)."""
        kernels.observations(self._p, self.pose, self.vel, self.count, self.pos, self.mvel, self.centre,
                             self.radius, self.slot, self._obs, self._all if rows is None else rows)
        return self._obs.copy()

    # -- episodes ---------------------------------------------------------------------------------------
    def seed(self, i: int, seed: int | None) -> None:
        """Seed copy ``i``'s generator as ``ApproachGroupEnv.reset(seed=...)`` seeds the single env's."""
        self.rngs[i] = seeding.np_random(seed)[0]

    def reset(self, i: int, options: dict | None = None) -> dict[str, Any]:
        """Start copy ``i``'s next episode (``ApproachGroupEnv.reset``, same ``options``); returns its reset info."""
        rng = self.rngs[i]
        n, formation, start = apply_reset_options(self.scenario.sample(rng), options)
        centre, layout, pose = spawn_layout(rng, self.world_params, self.robot_params, self.social, n, formation,
                                            start, self.groups)
        g = Group(self.social, centre, layout, self._keep)
        g.update_centre(pose[:2])
        self.pose[i], self.vel[i], self.queue[i] = pose, 0.0, 0.0
        self.count[i] = n
        for name, value in (("pos", g.pos), ("mvel", g.vel), ("myaw", g.yaw), ("force", g.force),
                            ("repulsion", g.repulsion), ("ring_offset", g.ring_offset), ("comfort", g.comfort)):
            arr = getattr(self, name)
            arr[i] = 0.0
            arr[i, :n] = value
        self.centre0[i], self.centre[i], self.robot_force[i] = g.centre0, g.centre, g.robot_force
        self.base_radius[i], self.joined_radius[i] = g.base_radius, g.joined_radius
        self.join_radius[i], self.keep[i], self.shift[i] = g.join_radius, g.keep, g.centre_shift
        self.radius[i], self.join_weight[i] = g.radius, g.join_weight
        self.steps[i], self.prev_accel[i], self.sums[i] = 0, 0.0, 0.0
        self.slot[i] = g.free_slot(pose[:2])
        self.clearance[i] = 0.0
        half = (self.robot_params.length / 2, self.robot_params.width / 2)
        self.clearance[i, :n] = box_circle_distance(pose, half, g.pos) - self.social.human_radius
        one = np.zeros(1)
        kernels.potentials(self._p, self.pose[i:i + 1], self.slot[i:i + 1], self.centre[i:i + 1],
                           self.radius[i:i + 1], np.zeros(1), one)
        self.potential[i] = one[0]
        return {"n_humans": n, "formation": formation, "start": start}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance every copy by one control period (``ApproachGroupEnv.step``, actions (N, A) in [-1, 1]).

        Returns rewards (N,), terminated (N,) and truncated (N,); ``success``, ``violation`` and ``collision``
        hold the last step's flags. Finished copies keep their final state until ``reset(i)``.
        """
        a = np.ascontiguousarray(actions, dtype=np.float64).reshape(self.num, self.n_act)
        kernels.step(self._p, self._w, a, self.pose, self.vel, self.queue, self.count, self.pos, self.mvel,
                     self.myaw, self.centre0, self.base_radius, self.joined_radius, self.join_radius,
                     self.ring_offset, self.comfort, self.keep, self.shift, self.centre, self.radius,
                     self.join_weight, self.force, self.repulsion, self.robot_force, self.steps, self.prev_accel,
                     self.clearance, self.slot, self.potential, self.sums, self.rewards, self.flags)
        return self.rewards.copy(), self.flags[:, 0].copy(), self.flags[:, 1].copy()

    def episode_terms(self, i: int) -> dict[str, float]:
        """Copy ``i``'s sums of every term and of the reward so far (the single env's ``episode_terms``)."""
        return dict(zip((*TERMS, "reward"), self.sums[i].tolist(), strict=True))
