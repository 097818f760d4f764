"""N episodes of the approaching task stepped together with array operations (training throughput).

``BatchedApproach`` is ``ApproachGroupEnv`` (Vector observation) for N independent copies, without PyBullet:
the base and the members move by ``batch_dynamics`` and the free slot, the rewards (eqs. 11-15 with our terms) and
the observation come from the array forms of the single env's functions. One step of all copies costs a few
hundred microseconds however many copies there are, where N single envs cost N times one step (each ~200 us,
mostly numpy's fixed cost per call on arrays of 2-6 agents). Resets (rare) spawn through the single env's own code
(``world.spawn_layout``, ``humans.Group``), so a copy seeded like a single env plays the same episode:
``tests/test_batched.py`` steps both with the same actions and compares every state, reward and ending.

The single env stays the reference, used for evaluation, rendering, metrics and deploy; this class serves
training (``training.vec_env.BatchedVecEnv`` wraps it for SB3). Per-step infos carry what training reads
(``is_success`` and ``episode_terms`` at an episode's end), not the single env's per-step ``terms``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from ..params import RobotParams, SocialParams, WorldParams, from_dict
from . import observation as ob
from .angles import wrap
from .approach import _params
from .batch_dynamics import BaseBatch, GroupBatch
from .humans import Group
from .reward import (
    TERMS,
    RewardWeights,
    proximity_cost,
    reward_term_matrix,
    route_distances,
    slot_potential,
    weight_vector,
)
from .scenarios import ScenarioMix
from .task import TaskParams
from .world import MAX_HUMANS, box_circle_distance, spawn_layout

FAR = 1.0e6  # clearance (m) reported for padding members: never near, never closing


class BatchedApproach:
    """N copies of the approaching task; ``reset(i)`` starts copy i's next episode, ``step`` advances all."""

    def __init__(self, num: int, scenario: str = "default", world: WorldParams | dict | None = None,
                 robot: RobotParams | dict | None = None, social: SocialParams | dict | None = None,
                 reward: RewardWeights | dict | None = None, task: TaskParams | dict | None = None) -> None:
        if not isinstance(num, int) or num < 1:
            raise ValueError(f"number of copies {num!r}: expected an integer >= 1")
        self.num = num
        self.scenario = ScenarioMix(scenario)
        self.world_params = _params(WorldParams, world, "world")
        self.robot_params = _params(RobotParams, robot, "robot")
        self.social = _params(SocialParams, social, "social")
        self.weights = _params(RewardWeights, reward, "reward")
        self.task = _params(TaskParams, task, "task")
        self.world_params.check_fits(self.social)
        biggest = max(max(sc.sizes) for sc in self.scenario.members)
        WorldParams(**{**self.world_params.__dict__, "n_humans": biggest}).check_fits(self.social)
        self.dt = self.world_params.dt
        self.n_act = 3 if self.task.turn else 2
        self._w = weight_vector(self.weights)
        self.base = BaseBatch(self.robot_params, self.dt, num)
        self.group = GroupBatch(self.social, num, MAX_HUMANS)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(num)]
        self.steps = np.zeros(num, dtype=int)
        self.prev_accel = np.zeros((num, 2))
        self.clearance = np.full((num, MAX_HUMANS), FAR)
        self.slot = np.zeros((num, 2))
        self.potential = np.zeros(num)
        self.sums = np.zeros((num, len(TERMS) + 1))  # episode sums of the terms and of the reward
        rp = self.robot_params
        self._half = (rp.length / 2, rp.width / 2)
        self._keep_out_extra = self.social.human_radius + rp.reach + self.task.intimate_zone + self.task.route_margin

    def set_reward_weights(self, **changes: float) -> None:
        """``ApproachGroupEnv.set_reward_weights`` for every copy."""
        self.weights = from_dict(RewardWeights, {**dataclasses.asdict(self.weights), **changes}, "reward")
        self._w = weight_vector(self.weights)

    # -- state ------------------------------------------------------------------------------------------
    def _route(self, xy: np.ndarray) -> np.ndarray:
        g = self.group
        return route_distances(xy, self.slot, g.centre, g.radius + self._keep_out_extra)

    def heading_error(self) -> np.ndarray:
        """Angle (rad) from each robot's heading to its conversation centre."""
        pose, c = self.base.pose, self.group.centre
        return wrap(np.arctan2(c[:, 1] - pose[:, 1], c[:, 0] - pose[:, 0]) - pose[:, 2])

    def _clearances(self) -> np.ndarray:
        pose, g = self.base.pose, self.group
        c, s = np.cos(pose[:, 2])[:, None], np.sin(pose[:, 2])[:, None]
        dx, dy = g.pos[..., 0] - pose[:, :1], g.pos[..., 1] - pose[:, 1:2]
        lx, ly = dx * c + dy * s, -dx * s + dy * c  # world -> body frame, as world.box_circle_distance
        ox = np.maximum(np.abs(lx) - self._half[0], 0.0)
        oy = np.maximum(np.abs(ly) - self._half[1], 0.0)
        return np.where(g.present, np.hypot(ox, oy) - self.social.human_radius, FAR)

    def _wall_contact(self) -> np.ndarray:
        """Whether each footprint touches a wall (``World.wall_clearance() <= 0`` on any side)."""
        sx, sy = self.world_params.room_size
        pose = self.base.pose
        hl, hw = self._half
        c, s = np.abs(np.cos(pose[:, 2])), np.abs(np.sin(pose[:, 2]))
        # the footprint's half-extent along x and y reaches a wall's inner face
        return (np.abs(pose[:, 0]) + (hl * c + hw * s) >= sx / 2) | (np.abs(pose[:, 1]) + (hl * s + hw * c) >= sy / 2)

    def observations(self) -> np.ndarray:
        """The Vector observations (N, OBS_SIZE) of the current states."""
        pose, g, rp = self.base.pose, self.group, self.robot_params
        sx, sy = self.world_params.room_size
        x, y = pose[:, 0], pose[:, 1]
        walls = np.stack([sx / 2 - x, x + sx / 2, sy / 2 - y, y + sy / 2], axis=1)
        return ob.vector_observations(pose, self.base.vel, g.pos, g.vel, g.present, g.centre, g.radius, self.slot,
                                      walls, rp.max_speed, rp.max_yaw_rate, pose[:, 2] if self.task.turn else None)

    # -- episodes ---------------------------------------------------------------------------------------
    def seed(self, i: int, seed: int | None) -> None:
        """Seed copy ``i``'s generator as ``ApproachGroupEnv.reset(seed=...)`` seeds the single env's."""
        self.rngs[i] = seeding.np_random(seed)[0]

    def reset(self, i: int) -> dict[str, Any]:
        """Start copy ``i``'s next episode (``ApproachGroupEnv.reset``); returns its reset info."""
        rng = self.rngs[i]
        n, formation, start = self.scenario.sample(rng)
        centre, angles, pose = spawn_layout(rng, self.world_params, self.robot_params, self.social, n, formation,
                                            start)
        group = Group(self.social, centre, angles)
        self.base.reset(i, pose)
        group.update_centre(self.base.pose[i, :2])
        self.group.set(i, group)
        self.steps[i] = 0
        self.prev_accel[i] = 0.0
        self.sums[i] = 0.0
        xy = self.base.pose[i:i + 1, :2]
        self.slot[i] = group.free_slot(xy[0])
        g = self.group
        self.potential[i] = slot_potential(route_distances(xy, self.slot[i:i + 1], g.centre[i:i + 1],
                                                           g.radius[i:i + 1] + self._keep_out_extra), 0.0)[0]
        half = self._half
        self.clearance[i] = FAR
        self.clearance[i, :n] = box_circle_distance(self.base.pose[i], half, group.pos) - self.social.human_radius
        return {"n_humans": n, "formation": formation, "start": start}

    def commands(self, actions: np.ndarray) -> np.ndarray:
        """Body-frame base commands (N, 3) for normalised actions (N, A) (``ApproachGroupEnv.command``)."""
        a = np.clip(np.asarray(actions, dtype=float), -1.0, 1.0)
        rp = self.robot_params
        if self.task.turn:
            return a * np.array([rp.max_speed, rp.max_speed, rp.max_yaw_rate])
        e = self.heading_error()
        turn = np.minimum(np.maximum(self.task.heading_gain * e, -rp.max_yaw_rate), rp.max_yaw_rate)
        c, s = np.cos(e), np.sin(e)
        cmd = np.empty((len(a), 3))
        cmd[:, 0] = (c * a[:, 0] - s * a[:, 1]) * rp.max_speed
        cmd[:, 1] = (s * a[:, 0] + c * a[:, 1]) * rp.max_speed
        cmd[:, 2] = turn
        return cmd

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance every copy by one control period (``ApproachGroupEnv.step``).

        Returns rewards (N,), terminated (N,) and truncated (N,); ``success``, ``violation`` and ``collision``
        hold the last step's flags. Finished copies keep their final state until ``reset(i)``.
        """
        base, g, task, dt = self.base, self.group, self.task, self.dt
        robot_before, members_before, vel_before = base.pose[:, :2], g.pos, base.vel[:, :2]
        potential_before = self.potential
        base.step(self.commands(actions))
        g.step(base.pose[:, :2], dt)
        self.steps += 1
        xy = base.pose[:, :2]
        self.slot = g.free_slot(xy)
        slot_after = np.hypot(self.slot[:, 0] - xy[:, 0], self.slot[:, 1] - xy[:, 1])
        clearance = self._clearances()
        nearest = clearance.min(axis=1)
        self.collision = (nearest <= 0.0) | self._wall_contact()
        self.violation = self.collision | (nearest < task.intimate_zone)
        speed = np.hypot(base.vel[:, 0], base.vel[:, 1])
        self.success = (~self.violation & (slot_after < task.slot_tolerance) & (speed < task.stop_speed)
                        & (np.abs(self.heading_error()) < math.radians(task.heading_tolerance_deg)))
        accel = (base.vel[:, :2] - vel_before) / dt
        self.potential = slot_potential(self._route(xy), speed)
        proximity = proximity_cost(self.clearance, clearance, task.intimate_zone, task.proximity_band)
        self.clearance = clearance
        terms = reward_term_matrix(g.robot_force, xy - robot_before, g.force, g.pos - members_before, g.repulsion,
                                   dt, accel, self.prev_accel, potential_before, self.potential, self.success,
                                   self.violation, proximity)
        rewards = terms @ self._w
        self.prev_accel = accel
        self.sums[:, :-1] += terms
        self.sums[:, -1] += rewards
        terminated = self.success | self.violation
        truncated = ~terminated & (self.steps >= task.max_steps)
        return rewards, terminated, truncated

    def episode_terms(self, i: int) -> dict[str, float]:
        """Copy ``i``'s sums of every term and of the reward so far (the single env's ``episode_terms``)."""
        return dict(zip((*TERMS, "reward"), self.sums[i].tolist(), strict=True))
