"""The approaching task's state for N copies and its step: the one engine behind every env.

``BatchedApproach`` keeps N episodes in arrays (the base's in ``base.BaseArrays``, the groups' in
``humans.GroupArrays``, padded to ``MAX_HUMANS`` members, the task's here) and advances all of them with one call
of ``kernels.step``. Training runs it with N copies (``training.vec_env.BatchedVecEnv``); the Gymnasium env
``ApproachGroupEnv`` is a batch of one with a PyBullet scene for rendering; so a copy seeded like a single env
plays the same episode, by construction. Resets draw the room and spawn in Python (``rooms``, ``spawn.spawn_layout``,
``GroupArrays.spawn``). Each copy's room is a row of ``room`` (``kernels.ROOM_X`` ...); the distance fields of
furnished rooms live in ``fields``, one slot per copy, the map room's in one more slot shared by every copy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from ...core import observation as ob
from ...core.actions import take_over
from ...core.base import BaseArrays, BaseParams
from ...core.humans import KEEP, MAX_HUMANS, RADIUS, GroupArrays, free_slot, sffm_params
from ...core.layouts import GroupModel, member_keep_out, slot_keep
from ...core.range_memory import MEMORY_REACH, RangeMemory
from ...core.range_sensors import RETURN_MARGIN, brake_for_bodies, lasers_see_body
from ...core.reward import TERMS, RewardWeights, weight_vector
from ...core.shield import ShieldParams, brake_returns
from ...core.task import TaskParams
from ...errors import UserError
from ...params import RobotParams, SocialParams, WorldParams, from_dict
from ..rooms.obstacles import CAP, CELL
from ..rooms.planner import way_in_for_group
from ..rooms.rooms import FurnitureParams, Room, furnished_room
from ..rooms.scenarios import apply_reset_options
from ..rooms.spawn import NoPlace, spawn_layout
from . import kernels
from .env_params import parse_env_params

SPAWN_TRIES = 20  # groups in the map room, or furnished rooms, tried for one episode (each 1000 places)


class BatchedApproach:
    """N copies of the approaching task; ``reset(i)`` starts copy i's next episode, ``step`` advances all."""

    def __init__(self, num: int, scenario: str = "default", world: WorldParams | dict | None = None,
                 robot: RobotParams | dict | None = None, social: SocialParams | dict | None = None,
                 reward: RewardWeights | dict | None = None, task: TaskParams | dict | None = None,
                 groups: str | GroupModel | None = None, groups_yaml: str | None = None,
                 room_yaml: str | list[str] | None = None, furniture: FurnitureParams | dict | None = None,
                 scan: bool = True, waypoints: bool = False, waypoints_near_group: bool = False,
                 perception: Any = None, member_order: str = "nearest") -> None:
        """``perception``: the observation model (``perception.groups.observation_model``): None/False, the true
        state (the default); True or a ``PerceptionParams`` (or a dict of its fields), the group as deploy's
        perception would see it, and the robot turning in place while it knows fewer than two people.
        ``member_order``: the order of the observation's member blocks (``observation.MEMBER_ORDERS``)."""
        if not isinstance(num, int) or num < 1:
            raise UserError(f"number of copies {num!r}: expected an integer >= 1")
        for name, flag in (("scan", scan), ("waypoints", waypoints), ("waypoints_near_group", waypoints_near_group)):
            if not isinstance(flag, bool):
                raise UserError(f"{name} = {flag!r}: expected true or false")
        self.num = num
        self.kwargs = {"scenario": scenario, "world": world, "robot": robot, "social": social, "reward": reward,
                       "task": task, "groups": groups, "groups_yaml": groups_yaml, "room_yaml": room_yaml,
                       "furniture": furniture, "scan": scan, "waypoints": waypoints,
                       "waypoints_near_group": waypoints_near_group, "perception": perception,
                       "member_order": member_order}  # ``like`` builds more
        self.waypoints = waypoints  # rooms with obstacles: the slot's entries show the way around them (planner)
        self.waypoints_near_group = waypoints_near_group  # ... up to the group's keep-out disc
        ep = parse_env_params(scenario, world, robot, social, reward, task, groups, groups_yaml, room_yaml, furniture)
        self.scenario, self.world_params, self.robot_params, self.social, self.weights, self.task, self.groups = ep[:7]
        self.furniture, self.map_rooms = ep.furniture, ep.map_rooms
        self.dt = self.world_params.dt
        self.n_act = 3 if self.task.turn else 2
        self.keep = slot_keep(self.social, self.robot_params.reach, self.task.intimate_zone,
                              self.task.route_margin)  # the robot's place from members (``layouts.slot_keep``)
        self._bparams = BaseParams.of(self.robot_params, self.dt)
        self._bp = np.array(self._bparams, dtype=float)
        self._sp = sffm_params(self.social, self.dt)
        try:
            self._tp = kernels.task_params(self.world_params, self.robot_params, self.social, self.task, member_order)
        except ValueError as exc:
            raise UserError(str(exc)) from None
        self.member_order = member_order
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(num)]
        self.bases, self.groups_state = BaseArrays(num, self._bparams), GroupArrays(num)
        m = MAX_HUMANS
        self.steps = np.zeros(num, dtype=np.int64)
        self.search_steps = np.zeros(num, dtype=np.int64)  # steps searching (observation model), time added
        self.prev_accel = np.zeros((num, 2))
        self.clearance = np.zeros((num, m))
        self.slot = np.zeros((num, 2))
        self.driven = np.ones(num, dtype=bool)  # the last step executed the policy's action (not deploy's search or
        #   a look in place, with the observation model)
        self.potential = np.zeros(num)
        self.sums = np.zeros((num, len(TERMS) + 1))  # episode sums of the terms and of the reward
        self.terms = np.zeros((num, len(TERMS)))  # the last step's terms
        self.rewards = np.zeros(num)
        self.flags = np.zeros((num, kernels.N_FLAGS), dtype=bool)  # kernels.TERMINATED ... OBSTACLE_COLLISION
        self.obs_size = ob.obs_size(scan)  # Vector observation entries (with the range scan or without)
        self._obs = np.zeros((num, self.obs_size), dtype=np.float32)
        self._all = np.arange(num)
        self._init_rooms()
        self.perceived = self._perception(perception)
        self._shield = ShieldParams.of(self)  # the robot's limits, for the range guard (``_range_guard``)
        copies = num if self.perceived is not None else 0  # the guard runs with the observation model only
        self._range_memory = [RangeMemory(self._shield.human_radius) for _ in range(copies)]  # ... and its memory

    def _perception(self, value: Any) -> Any:
        """The copies' perceived groups (``perception.groups.observation_model.PerceivedGroups``), or None for the true
        state."""
        # lazy: perception's tracker loads filterpy and scipy (~1 s), which only a perceiving env needs
        from ...perception.groups.observation_model import PerceivedGroups, PerceptionParams

        params = PerceptionParams.of(value)
        if params is None:
            return None
        return PerceivedGroups(self.num, self.robot_params, self.social, self.keep, self.groups.name == "paper",
                               params)

    def _init_rooms(self) -> None:
        """Room rows and the distance fields' slots (sized for the largest room the scenario may draw)."""
        self.empty_room = Room(self.world_params.room_size)
        self.rooms: list[Room] = [self.empty_room] * self.num
        self.room = np.zeros((self.num, kernels.N_ROOM))
        self.room[:, kernels.STEP_LIMIT] = self.task.max_steps
        self.room[:, kernels.ROOM_X], self.room[:, kernels.ROOM_Y] = self.empty_room.size
        self.room[:, kernels.FIELD], self.room[:, kernels.OBSTACLE] = -1, CAP
        shape, slots = (1, 1), 1
        if "furnished" in self.scenario.rooms:
            n = int(math.ceil(self.furniture.size_max / CELL - 1e-9)) + 1
            shape, slots = (n, n), self.num
        for room in self.map_rooms:  # after the copies' own slots, one each
            shape = tuple(max(a, b) for a, b in zip(shape, room.field.shape, strict=True))
            slots = self.num + len(self.map_rooms)
        self.fields = np.full((slots, *shape), CAP, dtype=np.float32)
        # each copy's way to its group (``planner.plan_map``), where it has obstacles and ``waypoints`` or the
        # task's ``geodesic_route`` is on
        planned = (self.waypoints or self.task.geodesic_route) and shape != (1, 1)
        self.plans = np.full((self.num, *shape) if planned else (1, 1, 1), np.inf, dtype=np.float32)
        for k, room in enumerate(self.map_rooms):
            self.fields[self.num + k, :room.field.shape[0], :room.field.shape[1]] = room.field
            self._check_map_room(room)

    def _check_map_room(self, room: Room) -> None:
        """A map room must hold the scenario's largest group and the robot: ``NoPlace`` names the file."""
        rng = np.random.default_rng(0)
        for sc in self.scenario.members:
            if sc.room == "map":
                for form in sc.formations:
                    self._spawn(rng, max(sc.sizes), form, sc.start, room)

    def _spawn(self, rng: np.random.Generator, n: int, formation: str, start: str, room: Room
               ) -> tuple[np.ndarray, Any, np.ndarray]:
        """``spawn_layout`` in ``room``; in the map room tried with ``SPAWN_TRIES`` groups before ``NoPlace``
        stands (a long row of members may find no place where a circle does)."""
        tries = SPAWN_TRIES if any(room is m for m in self.map_rooms) else 1
        for attempt in range(tries):
            try:
                return spawn_layout(rng, self.world_params, self.robot_params, self.social, n, formation, start,
                                    self.groups, room, self.keep, self.task)
            except NoPlace:
                if attempt == tries - 1:
                    raise
        raise AssertionError("unreachable")

    def _draw_room(self, i: int, kind: str, rng: np.random.Generator) -> Room:
        """Copy ``i``'s room for an episode in a room of ``kind`` (``scenarios.ROOMS``), set in its row."""
        if kind == "furnished":
            room = furnished_room(rng, self.furniture)
            f, slot = room.field, i
            self.fields[i] = CAP
            self.fields[i, :f.shape[0], :f.shape[1]] = f
        elif kind == "map":
            k = int(rng.integers(len(self.map_rooms))) if len(self.map_rooms) > 1 else 0  # one room: no draw
            room, slot = self.map_rooms[k], self.num + k
        else:
            room, slot = self.empty_room, -1
        self.rooms[i] = room
        row = self.room[i]
        row[kernels.ROOM_X], row[kernels.ROOM_Y] = room.size
        row[kernels.FIELD], row[kernels.FIELD_X0], row[kernels.FIELD_Y0] = slot, room.x0, room.y0
        return room

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
        """The Vector observations (N, OBS_SIZE) of the current states (recomputing ``rows`` only, if given): of
        the true group, or with the observation model of the perceived one."""
        rows = self._all if rows is None else rows
        g = self.perceived or self.groups_state
        slot = self.slot if self.perceived is None else self.perceived.slot
        kernels.observations(self._tp, self.pose, self.vel, g.count, g.pos, g.vel, g.centre, g.scalars, slot,
                             self.room, self.fields, self.plans, self._obs, rows)
        columns = [] if self.perceived is None else self.perceived.oracle_columns
        if columns:  # diagnostics: parts of it from the true state (``PerceptionParams.oracle``)
            t, true = self.groups_state, np.empty_like(self._obs)
            kernels.observations(self._tp, self.pose, self.vel, t.count, t.pos, t.vel, t.centre, t.scalars,
                                 self.slot, self.room, self.fields, self.plans, true, rows)
            for cols in columns:
                self._obs[rows, cols] = true[rows, cols]
        return self._obs.copy()

    # -- episodes ---------------------------------------------------------------------------------------
    def seed(self, i: int, seed: int | None) -> None:
        """Seed copy ``i``'s generator as ``ApproachGroupEnv.reset(seed=...)`` seeds the single env's (and the
        observation model's own)."""
        self.rngs[i] = seeding.np_random(seed)[0]
        if self.perceived is not None:
            self.perceived.seed(i, seed)

    def reset(self, i: int, options: dict | None = None) -> dict[str, Any]:
        """Start copy ``i``'s next episode (``reset(options=...)`` as ``ApproachGroupEnv``); returns its info."""
        rng = self.rngs[i]
        sc = self.scenario.pick(rng)
        n, formation, start = apply_reset_options(sc.sample(rng), options)
        for attempt in range(SPAWN_TRIES):  # a furnished room with no place is drawn again; in a map room, the
            room = self._draw_room(i, sc.room, rng)  # episode's group and start (1 in ~1,000 west-room draws)
            try:
                centre, layout, pose = self._spawn(rng, n, formation, start, room)
                break
            except NoPlace:
                if sc.room == "empty" or attempt == SPAWN_TRIES - 1:
                    raise
                if sc.room == "map":
                    n, formation, start = apply_reset_options(sc.sample(rng), options)
        self.bases.reset(i, pose)
        g = self.groups_state
        g.spawn(i, self.social, centre, layout, self.keep, pose[:2])
        self.steps[i], self.prev_accel[i], self.sums[i], self.terms[i], self.flags[i] = 0, 0.0, 0.0, 0.0, False
        self.search_steps[i] = 0
        self.slot[i] = free_slot(n, g.pos[i], *g.centre[i], g.scalars[i, RADIUS], g.scalars[i, KEEP], *pose[:2],
                                 True)
        self.clearance[i] = 0.0
        row = self.room[i]
        row[kernels.PLAN], row[kernels.START_X], row[kernels.START_Y] = 0.0, pose[0], pose[1]
        row[kernels.STEP_LIMIT], row[kernels.DETOUR_ADDED] = self.task.max_steps, 0.0
        if room.furnished:
            self._plan(i)
        kernels.clearances(self._tp, self.pose[i], n, g.pos[i], self.clearance[i])
        _, self.room[i, kernels.OBSTACLE] = kernels.static_clearance(self._tp, self.pose[i], self.room[i], self.fields)
        self.potential[i] = self.potential_of(i, 0.0)
        if self.perceived is not None:
            self.perceived.reset(i, self.pose[i], g.pos[i, :n], g.yaw[i, :n], self.dt)
            self._range_memory[i].clear()
        return {"n_humans": n, "formation": formation, "start": start}

    def _plan(self, i: int) -> None:
        """Copy ``i``'s way in and keep-out disc (``planner.way_in_for_group``): for its plan with ``waypoints``
        (made in ``kernels.observations`` the first time the slot is out of sight), and for the furniture's detour
        (``kernels.detour_steps``)."""
        g, n, row = self.groups_state, int(self.groups_state.count[i]), self.room[i]
        keep_out, row[kernels.WAY_X], row[kernels.WAY_Y], show = way_in_for_group(
            g.pos[i, :n], g.centre[i], self.slot[i],
            member_keep_out(self.social, self.robot_params.reach, self.task.intimate_zone), self.waypoints_near_group)
        row[kernels.KEEP_OUT], (row[kernels.PLAN_CX], row[kernels.PLAN_CY]) = keep_out, g.centre[i]
        row[kernels.PLAN] = show if self.waypoints else 0.0
        row[kernels.PLANNED] = 0.0
        if self.task.geodesic_route:  # the shaping reads it from the first step
            kernels.make_plan(self._tp, row, self.fields[int(row[kernels.FIELD])], self.plans[i])

    def potential_of(self, i: int, speed: float) -> float:
        """Copy ``i``'s shaping potential in its current state at ``speed`` (``kernels.potential`` with no
        previous value)."""
        g = self.groups_state
        return kernels.potential(self._tp, self.pose[i], self.slot[i], g.centre[i], g.scalars[i, RADIUS], speed,
                                 self.room[i], self.plans[min(i, len(self.plans) - 1)], np.nan)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance every copy by one control period (actions (N, A) in [-1, 1]).

        Returns rewards (N,), terminated (N,) and truncated (N,); ``success``, ``violation``, ``collision`` and
        ``terms`` hold the last step's. Finished copies keep their final state until ``reset(i)``.
        """
        a = np.ascontiguousarray(actions, dtype=np.float64).reshape(self.num, self.n_act)
        b, g = self.bases, self.groups_state
        aim = g.centre
        if self.perceived is not None:  # the robot faces the centre it perceives; knowing too few, it searches;
            # before a claim or when stalled it looks at members not seen lately (``looks.Looks``)
            speed = np.hypot(self.vel[:, 0], self.vel[:, 1])
            aim, search, looking = self.perceived.steer(self.pose, self.task.heading_gain, self.dt,
                                                        self._static_clearance, speed, self.task)
            aim = self._turn_guard(aim)
            lost = ~self.perceived.known  # the action pipeline's last stage: deploy drives these itself (its
            a = take_over(a, lost | looking, search, self.robot_params.max_speed)  # search, or a look in place)
            self.driven = ~(lost | looking)
            a = self._range_guard(a, aim)  # and deploy's guard for what the lasers see
            # searching is not approaching: its time is added to the episode, up to one episode more (deploy's
            # 60 s --duration is twice the simulated episode, for the search)
            more = lost & (self.search_steps < self.task.max_steps)
            self.search_steps[more] += 1
            self.room[more, kernels.STEP_LIMIT] += 1
        kernels.step(self._tp, self._bp, self._sp, self._w, a, b.pose, b.vel, b.queue, g.count, g.pos, g.vel, g.yaw,
                     g.centre0, g.centre, g.scalars, g.ring_offset, g.comfort, g.force, g.repulsion, g.robot_force,
                     self.steps, self.prev_accel, self.clearance, self.slot, self.potential, self.sums, self.terms,
                     self.rewards, self.flags, self.room, self.fields, self.plans, aim)
        if self.perceived is not None:  # the camera's frame of the new state, for the copies that go on
            over = self.flags[:, kernels.TERMINATED] | self.flags[:, kernels.TRUNCATED]
            for i in np.flatnonzero(~over).tolist():
                n = int(g.count[i])
                self.perceived.frame(i, self.pose[i], g.pos[i, :n], g.yaw[i, :n], self.dt)
        return self.rewards.copy(), self.flags[:, kernels.TERMINATED].copy(), self.flags[:, kernels.TRUNCATED].copy()

    def _range_guard(self, actions: np.ndarray, aim: np.ndarray) -> np.ndarray:
        """``actions`` with deploy's range guard on each copy's body command (``range_sensors.brake_for_bodies``,
        for ``RETURN_MARGIN`` beyond the intimate zone, as ``deploy.guards.Guards`` brakes): with the observation
        model the policy and its shield see only the members perception found, the lasers see the others in their
        fields, and deploy's ``RangeMemory`` remembers those no track explains for where they could stand in the
        lasers' blind sectors since (the bodies' centres remembered, deploy's the returns on them). Not modelled:
        the sonars."""
        g, turn, top = self.groups_state, self._tp[kernels.TURN] > 0, self.robot_params.max_speed
        out = np.array(actions, dtype=np.float64, copy=True)
        c, s = np.cos(self.pose[:, 2])[:, None], np.sin(self.pose[:, 2])[:, None]
        rel = g.pos - self.pose[:, None, :2]  # every copy's members in its robot frame at once (the hot path)
        local = np.stack([c * rel[..., 0] + s * rel[..., 1], -s * rel[..., 0] + c * rel[..., 1]], axis=-1)
        seen = lasers_see_body(local.reshape(-1, 2), self._shield.human_radius).reshape(local.shape[:2])
        seen &= np.arange(local.shape[1])[None, :] < g.count[:, None]
        sh, clearance = self._shield, self.task.intimate_zone + RETURN_MARGIN
        phantoms = self._phantoms(seen & (np.hypot(local[..., 0], local[..., 1]) <= MEMORY_REACH))
        # only bodies near enough to cut full speed: sqrt(2 a (c - c_min)) < top within c_min + top^2 / 2a
        gap = np.hypot(local[..., 0], local[..., 1]) - math.hypot(sh.half_length, sh.half_width) - sh.human_radius
        seen &= gap < clearance + top * top / (2.0 * sh.brake_accel)
        for i in sorted({*np.flatnonzero(seen.any(axis=1)).tolist(), *phantoms}):
            bodies = local[i, :int(g.count[i])]
            h = 0.0 if turn else kernels.heading_error(self.pose[i], aim[i])  # the action's frame -> the body's
            rot = np.array([[math.cos(h), -math.sin(h)], [math.sin(h), math.cos(h)]])
            v = rot @ np.clip(out[i, :2], -1.0, 1.0) * top
            v = brake_for_bodies(v, bodies, clearance, sh)
            if i in phantoms:
                v = brake_returns(v, phantoms[i], clearance, sh, radius=sh.human_radius)
            out[i, :2] = rot.T @ v / top
        return out

    def _phantoms(self, seen: np.ndarray) -> dict[int, np.ndarray]:
        """Each copy's ``RangeMemory`` told of the members its lasers see now (``seen`` (N, MAX_HUMANS), within the
        memory's reach) on the episode's clock, with the members perception tracks as the people that explain
        them; returns, by copy, where those remembered could stand unseen now (robot frame)."""
        out = {}
        for i in range(self.num):
            n, memory, now = int(self.groups_state.count[i]), self._range_memory[i], float(self.steps[i]) * self.dt
            people = self.perceived.pos[i, :int(self.perceived.count[i])]
            memory.update(self.groups_state.pos[i, :n], seen[i, :n], now, people, self.pose[i])
            if len(memory.points):
                found = memory.phantoms(self.pose[i], now)
                if len(found):
                    out[i] = found
        return out

    TURN_CLEARANCE = 0.05  # m: a turn that would bring the footprint's corner nearer furniture than this is held

    def _turn_guard(self, aim: np.ndarray) -> np.ndarray:
        """``aim`` with the turn held (aim straight ahead) for copies whose next period's turn would swing the
        footprint's corner into a wall or furniture: with the observation model the aim jumps (the search's turn,
        the centre found at last) and the robot turns up to 1 rad/s in place, where, beside furniture, its 0.32 m
        corner hit what the 0.23 m side cleared (1.5-3 % of map-room starts). The turn waits for the policy to
        move off."""
        out = aim.copy()
        for i in range(self.num):
            pose = self.pose[i]
            turn = self.task.heading_gain * kernels.heading_error(pose, aim[i])
            turn = max(-self.robot_params.max_yaw_rate, min(self.robot_params.max_yaw_rate, turn)) * self.dt
            if abs(turn) < 1e-6:
                continue
            now = self._static_clearance(i, pose)
            then = self._static_clearance(i, np.array([pose[0], pose[1], pose[2] + turn]))
            if then < self.TURN_CLEARANCE and then < now:
                out[i] = pose[:2] + np.array([math.cos(pose[2]), math.sin(pose[2])])
        return out

    def _static_clearance(self, i: int, pose: np.ndarray) -> float:
        """Copy ``i``'s footprint's clearance (m) to walls and furniture at ``pose`` (x, y, yaw)."""
        return float(min(kernels.static_clearance(self._tp, np.asarray(pose, dtype=float), self.room[i], self.fields)))

    def keep_out(self, i: int, margin: float) -> float:
        """Radius around copy ``i``'s conversation centre the shaping's way to the slot keeps out of: the
        footprint's corners, not its mean radius, must stay out of the intimate zone (plus ``margin``)."""
        return float(self.radius[i]) + member_keep_out(self.social, self.robot_params.reach, self.task.intimate_zone) \
            + margin

    def snapshot(self, i: int, t: float) -> dict[str, Any]:
        """Copy ``i``'s state at time ``t`` as recorded in trajectories (metrics, plots, videos): copies."""
        g, n = self.groups_state, int(self.groups_state.count[i])
        wall, _ = kernels.static_clearance(self._tp, self.pose[i], self.room[i], self.fields)
        return {"t": t, "robot": self.pose[i].copy(), "robot_vel": self.vel[i].copy(), "members": g.pos[i, :n].copy(),
                "members_yaw": g.yaw[i, :n].copy(), "centre": g.centre[i].copy(), "radius": float(self.radius[i]),
                "slot": self.slot[i].copy(), "clearance": self.clearance[i, :n].copy(),
                "wall": float(wall),  # the footprint's clearance to the nearest wall ...
                "obstacle": float(min(wall, self.room[i, kernels.OBSTACLE])),  # ... and to anything static
                # the SFFM's repulsion on the robot and on the members (metrics' social work)
                "social_force": float(np.hypot(*g.robot_force[i, 2:]) + np.hypot(*g.repulsion[i, :n].T).sum())}

    def room_info(self, i: int) -> dict[str, Any]:
        """Copy ``i``'s room as the first state of a recorded trajectory carries it (plots draw it): its size (m)
        and obstacles ((B, 5) ``(cx, cy, size_x, size_y, yaw)``)."""
        room = self.rooms[i]
        return {"room_size": room.size, "obstacles": room.boxes()}

    def outcome(self, i: int) -> dict[str, Any]:
        """Copy ``i``'s last step as the env's ``info`` reports it (at an episode's end: ``episode_terms``)."""
        f = self.flags[i]
        info: dict[str, Any] = {"terms": dict(zip(TERMS, self.terms[i].tolist(), strict=True)),
                                "success": bool(f[kernels.SUCCESS]), "collision": bool(f[kernels.COLLISION]),
                                "obstacle_collision": bool(f[kernels.OBSTACLE_COLLISION]),
                                "violation": bool(f[kernels.VIOLATION]),
                                "slot_distance": float(np.hypot(*(self.slot[i] - self.pose[i, :2])))}
        if f[kernels.TERMINATED] or f[kernels.TRUNCATED]:
            info["episode_terms"] = self.episode_terms(i)
            info["is_success"] = info["success"]  # SB3's convention for success-rate logging
            if self.perceived is not None:
                info["perceived"] = self.perceived_outcome(i)
        return info

    def perceived_outcome(self, i: int) -> dict[str, float]:
        """With the observation model, where copy ``i``'s perception left it: the perceived place's distance (m)
        from the true one (inf: too few people known for a group), the robot's from the perceived place, and how
        many true members perception never knew (none of its people within ``GroupParams.same_person_m``)."""
        g, n, p = self.groups_state, int(self.groups_state.count[i]), self.perceived
        cp = p.copies[i]
        known = np.array([m.pos for m in cp.members]).reshape(-1, 2)
        near = cp.tracker.p.same_person_m
        unfound = sum(1 for xy in g.pos[i, :n] if not len(known) or np.hypot(*(known - xy).T).min() > near)
        return {"slot_error_m": float(np.hypot(*(p.slot[i] - self.slot[i]))) if p.known[i] else math.inf,
                "place_distance_m": float(np.hypot(*(p.slot[i] - self.pose[i, :2]))) if p.known[i] else math.inf,
                "members_unfound": float(unfound)}

    def episode_terms(self, i: int) -> dict[str, float]:
        """Copy ``i``'s sums of every term and of the reward so far."""
        return dict(zip((*TERMS, "reward"), self.sums[i].tolist(), strict=True))
