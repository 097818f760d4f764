"""The way to the group through furnished rooms (env/rooms/planner.py): distances by hand, waypoints around a wall, and
the observation's slot entries with and without waypoints, in the env and in deploy."""

import math
from pathlib import Path

import numpy as np
import pytest

from ssbl_pb.core.observation import POS_SCALE
from ssbl_pb.deploy.frames import Frames, RoomMap
from ssbl_pb.env.rooms import planner
from ssbl_pb.env.rooms.obstacles import CELL, box_rows
from ssbl_pb.env.rooms.rooms import Room

# a 6 x 6 m room split by a wall along x = 0 from y = -3 to y = 1.5: the way round is through the gap above it
WALL = Room((6.0, 6.0), box_rows(np.array([[0.0, -0.75, 0.2, 4.5, 0.0]])), "wall")
EMPTY = Room((6.0, 6.0), box_rows(np.array([[2.9, 2.9, 0.05, 0.05, 0.0]])), "corner")  # a speck in a corner


def plan(room: Room, goal: tuple[float, float], clearance: float = 0.4) -> np.ndarray:
    out = np.empty_like(room.field)
    assert planner.plan_map(room.field, room.x0, room.y0, *room.size, clearance, 10.0, 10.0, 0.0, *goal, out)
    return out


def node(room: Room, x: float, y: float) -> tuple[int, int]:
    return int(round((y - room.y0) / CELL)), int(round((x - room.x0) / CELL))


def test_distances_are_octile_in_an_open_room_and_go_round_a_wall():
    d = plan(EMPTY, (1.0, 0.0))
    # 1 m along x and 0.5 m along y from the goal: 10 diagonal (1.5 cells each) and 10 straight steps of 5 cm
    assert d[node(EMPTY, 2.0, 0.5)] == pytest.approx(10 * 1.5 * CELL + 10 * CELL, abs=1e-6)
    assert d[node(EMPTY, 1.0, 0.0)] == 0.0
    assert not np.isfinite(d[node(EMPTY, 2.9, 0.0)])  # within the clearance of the wall
    w = plan(WALL, (1.0, -1.0))
    # from (-1, -1), 2 m away straight through the wall: the way round passes the gap above y = 1.5 + 0.4
    assert w[node(WALL, -1.0, -1.0)] > 2 * math.hypot(1.0, 2.9) - 0.01
    assert w[node(WALL, 0.0, 0.0)] == np.inf  # inside the wall


def test_waypoint_leads_toward_the_gap_and_in_sight_sees_the_wall():
    w = plan(WALL, (1.0, -1.0))
    wx, wy, found = planner.waypoint(w, WALL.x0, WALL.y0, -1.0, -1.0)
    assert found
    assert math.hypot(wx + 1.0, wy + 1.0) <= planner.AHEAD + 1e-6
    assert wy > -1.0 + 0.9 * planner.AHEAD * math.sqrt(0.5)  # up toward the gap, not at the wall
    assert not planner.in_sight(WALL.field, WALL.x0, WALL.y0, -1.0, -1.0, 1.0, -1.0, 0.32)
    assert planner.in_sight(WALL.field, WALL.x0, WALL.y0, -1.0, 2.5, 1.0, 2.5, 0.32)  # above the wall
    # at the goal there is nowhere further to go: the slot is shown instead
    assert not planner.waypoint(w, WALL.x0, WALL.y0, 1.0, -1.0)[2]


def test_a_cut_off_way_in_has_no_plan():
    out = np.empty_like(WALL.field)
    # the way in inside the wall and farther than 0.5 m from any free node: no plan
    assert not planner.plan_map(WALL.field, WALL.x0, WALL.y0, 6.0, 6.0, 0.9, 10.0, 10.0, 0.0, 0.0, -1.5, out)


def _slot_entries(sim, obs):
    x, y = sim.pose[0, :2]
    frame = math.atan2(sim.centre[0, 1] - y, sim.centre[0, 0] - x)
    c, s = math.cos(frame), math.sin(frame)
    sx, sy = sim.slot[0] - sim.pose[0, :2]
    return np.array([c * sx + s * sy, c * sy - s * sx]) / POS_SCALE, obs[:2]


def test_the_env_shows_the_way_while_the_slot_is_out_of_sight():
    from ssbl_pb.env.engine.kernels import PLAN, PLANNED
    from ssbl_pb.env.gymenv.approach import make_env

    shown = 0
    plain = make_env(scenario="default@furnished")
    with_way = make_env(scenario="default@furnished", waypoints=True)
    for seed in range(40):
        o_plain, _ = plain.reset(seed=seed)
        slot, got = _slot_entries(plain.unwrapped.sim, o_plain)
        assert np.allclose(got, slot, atol=1e-5)  # without waypoints: always the slot
        o, _ = with_way.reset(seed=seed)
        sim = with_way.unwrapped.sim
        room = sim.rooms[0]
        x, y = sim.pose[0, :2]
        slot, got = _slot_entries(sim, o)
        blocked = not planner.in_sight(room.field, room.x0, room.y0, x, y, *sim.slot[0], sim.robot_params.reach)
        assert sim.room[0, PLAN] > 0  # a plan to make (spawning guarantees a way in) ...
        assert sim.room[0, PLANNED] == (1.0 if blocked else 0.0)  # ... made only where the slot is out of sight
        if blocked:
            shown += 1
            assert not np.allclose(got, slot, atol=1e-3)
            assert np.hypot(*got) * POS_SCALE == pytest.approx(planner.AHEAD, abs=0.15)
        else:
            assert np.allclose(got, slot, atol=1e-5)
    assert shown >= 3  # furnished rooms do hide the slot at some starts


def test_deploy_shows_the_same_waypoint_from_the_map():
    room = RoomMap(Path("wall.yaml"), WALL.size, np.zeros(3), None, WALL)
    frames = Frames(room, np.zeros(3))
    members = np.array([[2.0, -1.8], [2.0, -0.2]])  # a pair right of the wall, its place on its left
    centre, slot = members.mean(axis=0), np.array([1.0, -1.0])
    pose = np.array([-1.5, -1.0, 0.0])
    got = frames.way_to(pose, members, centre, slot, 0.32, 0.5)
    out = np.empty_like(WALL.field)
    keep_out, wx, wy, radius = planner.way_in_for_group(members, centre, slot, 0.5)
    assert (keep_out, wx, wy) == pytest.approx((1.3, 2.0 - 1.3 - planner.ENTRY_BEYOND, -1.0))
    assert radius == pytest.approx(1.3 + planner.ENTRY_BEYOND + planner.WAY_IN_ZONE)
    assert planner.way_in_for_group(members, centre, slot, 0.5, near_group=True)[3] == pytest.approx(1.3)
    assert planner.plan_map(WALL.field, WALL.x0, WALL.y0, *WALL.size, 0.42, *centre, keep_out, wx, wy, out)
    wx, wy, found = planner.waypoint(out, WALL.x0, WALL.y0, -1.5, -1.0)
    assert found and np.allclose(got, [wx, wy])
    assert wy > -1.0  # up toward the gap
    assert np.allclose(Frames().way_to(pose, members, centre, slot, 0.32, 0.5), slot)  # no map: the slot


def test_bad_flags_name_themselves():
    from ssbl_pb.core.reward import RewardWeights
    from ssbl_pb.env.gymenv.approach import make_env
    from ssbl_pb.errors import UserError

    with pytest.raises(UserError, match="waypoints = 'yes': expected true or false"):
        make_env(scenario="default@furnished", waypoints="yes")
    with pytest.raises(UserError, match="w_disp"):
        RewardWeights(w_disp=-1.0)
    with pytest.raises(UserError, match="waypoints_near_group = 1: expected true or false"):
        make_env(scenario="default@furnished", waypoints=True, waypoints_near_group=1)
    with pytest.raises(UserError, match="geodesic_route = 'yes': expected true or false"):
        make_env(scenario="default@furnished", task={"geodesic_route": "yes"})


def test_the_furnitures_detour_extends_the_episode():
    """``kernels.detour_steps``: the way round the wall minus the way through the empty room (same grid metric),
    at the top speed; nothing where the way is straight."""
    from ssbl_pb.env.engine import kernels
    from ssbl_pb.env.gymenv.approach import ApproachGroupEnv

    tp = ApproachGroupEnv().unwrapped.sim._tp
    row = np.zeros(kernels.N_ROOM)
    row[[kernels.ROOM_X, kernels.ROOM_Y, kernels.FIELD_X0, kernels.FIELD_Y0]] = (*WALL.size, WALL.x0, WALL.y0)
    row[[kernels.WAY_X, kernels.WAY_Y, kernels.KEEP_OUT, kernels.PLAN_CX, kernels.PLAN_CY]] = (1.0, -1.0, 0.0,
                                                                                              10.0, 10.0)
    row[[kernels.START_X, kernels.START_Y]] = (-1.0, -1.0)
    clearance, step = tp[kernels.PLAN_CLEARANCE], tp[kernels.MAX_SPEED] * tp[kernels.DT]
    through = plan(EMPTY, (1.0, -1.0), clearance)[node(EMPTY, -1.0, -1.0)]  # 2 m straight on the grid
    round_ = plan(WALL, (1.0, -1.0), clearance)[node(WALL, -1.0, -1.0)]
    assert through == pytest.approx(2.0) and round_ > 5.0
    assert kernels.detour_steps(tp, row, WALL.field) == math.ceil((round_ - through) / step)
    row[[kernels.START_X, kernels.START_Y]] = (2.0, -1.0)  # the same side of the wall: no detour
    assert kernels.detour_steps(tp, row, WALL.field) == 0


def test_plan_distance_interpolates_and_reads_nearby_nodes():
    d = plan(EMPTY, (1.0, 0.0))
    at = d[node(EMPTY, 2.0, 0.5)]
    assert planner.plan_distance(d, EMPTY.x0, EMPTY.y0, 2.0, 0.5) == pytest.approx(at, abs=1e-6)
    between = 0.5 * (d[node(EMPTY, 2.0, 0.5)] + d[node(EMPTY, 2.05, 0.5)])
    assert planner.plan_distance(d, EMPTY.x0, EMPTY.y0, 2.025, 0.5) == pytest.approx(between, abs=1e-6)
    # inside the wall's clearance (the last free node is at x = 2.55): that node plus the 0.15 m to it
    assert not np.isfinite(d[node(EMPTY, 2.6, 0.0)])
    assert planner.plan_distance(d, EMPTY.x0, EMPTY.y0, 2.7, 0.0) == pytest.approx(d[node(EMPTY, 2.55, 0.0)] + 0.15)
    w = plan(WALL, (1.0, -1.0))
    assert planner.plan_distance(w, WALL.x0, WALL.y0, 0.0, -1.0) == np.inf  # 0.5 m inside: nothing near enough


def test_the_shaping_goes_round_furniture_only_with_geodesic_route():
    """``kernels.route_to_slot``: the way round the wall to the way in, then in; without ``geodesic_route`` (or
    inside the group's disc) the way round the group only; ``potential`` keeps the last value off the map."""
    from ssbl_pb.core.reward import route_length, slot_potential
    from ssbl_pb.env.engine import kernels
    from ssbl_pb.env.gymenv.approach import ApproachGroupEnv

    plain = ApproachGroupEnv().unwrapped.sim._tp
    geodesic = ApproachGroupEnv(task={"geodesic_route": True}).unwrapped.sim._tp
    row = np.zeros(kernels.N_ROOM)
    row[[kernels.ROOM_X, kernels.ROOM_Y, kernels.FIELD_X0, kernels.FIELD_Y0]] = (*WALL.size, WALL.x0, WALL.y0)
    row[[kernels.WAY_X, kernels.WAY_Y, kernels.KEEP_OUT, kernels.PLAN_CX, kernels.PLAN_CY]] = (1.0, -1.0, 0.5,
                                                                                              2.5, -1.0)
    way = np.empty_like(WALL.field)
    kernels.make_plan(geodesic, row, WALL.field, way)
    assert row[kernels.PLANNED] == 1.0
    slot, centre, radius = np.array([1.6, -1.0]), np.array([2.5, -1.0]), 0.3
    keep = radius + geodesic[kernels.KEEP_OUT_EXTRA]
    pose = np.array([-1.0, -1.0, 0.0])
    round_group = route_length(-1.0, -1.0, *slot, *centre, keep)
    in_from_way = route_length(1.0, -1.0, *slot, *centre, keep)
    assert kernels.route_to_slot(plain, pose, slot, centre, radius, row, way) == pytest.approx(round_group)
    got = kernels.route_to_slot(geodesic, pose, slot, centre, radius, row, way)
    assert got == pytest.approx(way[node(WALL, -1.0, -1.0)] + in_from_way, abs=1e-5)
    assert got > round_group + 3.0  # up round the wall's end and back down
    inside = np.array([2.0, -1.0, 0.0])  # within the group's disc: the way round the group
    assert kernels.route_to_slot(geodesic, inside, slot, centre, radius, row, way) == pytest.approx(
        route_length(2.0, -1.0, *slot, *centre, keep))
    in_wall = np.array([0.0, -1.0, 0.0])
    assert kernels.potential(geodesic, in_wall, slot, centre, radius, 0.0, row, way, -7.5) == -7.5
    assert kernels.potential(geodesic, in_wall, slot, centre, radius, 0.0, row, way, np.nan) == pytest.approx(
        slot_potential(route_length(0.0, -1.0, *slot, *centre, keep), 0.0))  # no previous: round the group
    assert kernels.potential(geodesic, pose, slot, centre, radius, 0.0, row, way, -7.5) == pytest.approx(
        slot_potential(got, 0.0))


def test_geodesic_route_plans_every_furnished_episode_and_never_shortens_the_way():
    from ssbl_pb.env.engine import kernels
    from ssbl_pb.env.gymenv.approach import make_env

    env = make_env(scenario="default@furnished", task={"geodesic_route": True})
    plain = make_env(scenario="default@furnished")
    longer = 0
    for seed in range(20):
        env.reset(seed=seed)
        plain.reset(seed=seed)
        sim, ref = env.unwrapped.sim, plain.unwrapped.sim
        assert sim.room[0, kernels.PLANNED] == 1.0  # made at the start: the shaping reads it from the first step
        assert np.allclose(sim.pose, ref.pose)  # same episode
        assert sim.potential[0] <= ref.potential[0] + 1e-9  # never a shorter way than round the group
        longer += sim.potential[0] < ref.potential[0] - 0.5
    assert longer >= 1  # furniture does lengthen some ways


def test_way_length_is_the_plans_distance_at_the_start():
    """``planner.way_length`` (A* to one point) against ``plan_map`` (the whole room) in furnished rooms: the
    same metres from the way in, with or without the obstacles, also from starts inside an obstacle's margin."""
    from ssbl_pb.env.rooms.rooms import FurnitureParams, furnished_room

    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(12):
        room = furnished_room(rng, FurnitureParams())
        for _ in range(10):
            cx, cy = rng.uniform(-2, 2, 2)
            keep_out, wx, wy = 1.2, cx + 1.3, cy
            sx, sy = rng.uniform(-room.size[0] / 2 + 0.3, room.size[0] / 2 - 0.3), rng.uniform(
                -room.size[1] / 2 + 0.3, room.size[1] / 2 - 0.3)
            for obstacles in (True, False):
                field = room.field if obstacles else np.full_like(room.field, 10.0)
                ref = np.empty_like(field)
                made = planner.plan_map(field, room.x0, room.y0, *room.size, 0.42, cx, cy, keep_out, wx, wy, ref)
                got = planner.way_length(room.field, room.x0, room.y0, *room.size, 0.42, cx, cy, keep_out, wx, wy,
                                         sx, sy, obstacles)
                i, j = node(room, sx, sy)
                want = ref[i, j] if np.isfinite(ref[i, j]) else ref[max(i - 1, 0):i + 2, max(j - 1, 0):j + 2].min()
                assert got == pytest.approx(want if made else np.inf, abs=1e-6)
                checked += np.isfinite(got)
    assert checked > 150  # most of them have a way


def test_waypoints_near_the_group_are_shown_up_to_its_disc():
    """``waypoints_near_group``: the plan's way is shown right up to the group's keep-out disc (a policy trained
    with it reads it from its config: ``trained.OBSERVATION_KEYS``)."""
    from ssbl_pb.agents.trained import policy_env_kwargs
    from ssbl_pb.env.engine import kernels
    from ssbl_pb.env.gymenv.approach import make_env

    near = make_env(scenario="default@furnished", waypoints=True, waypoints_near_group=True)
    far = make_env(scenario="default@furnished", waypoints=True)
    for seed in range(5):
        near.reset(seed=seed)
        far.reset(seed=seed)
        a, b = near.unwrapped.sim.room[0], far.unwrapped.sim.room[0]
        assert a[kernels.PLAN] == pytest.approx(a[kernels.KEEP_OUT])
        assert b[kernels.PLAN] == pytest.approx(b[kernels.KEEP_OUT] + planner.ENTRY_BEYOND + planner.WAY_IN_ZONE)
    assert policy_env_kwargs("vector").get("waypoints_near_group") is True  # the shipped policy's
