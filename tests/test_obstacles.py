"""Obstacles: box distances, the distance field, the footprint's clearance and the range scan against hand
computations; furnished rooms and where episodes start in them."""

import math

import numpy as np
import pytest

from ssbl_pb.env.rooms import obstacles as obs
from ssbl_pb.env.rooms.obstacles import CAP, CELL, box_distance, box_rows, boxes_distance, field_at, ray_range
from ssbl_pb.env.rooms.rooms import FurnitureParams, Room, furnished_room
from ssbl_pb.params import RobotParams

HL, HW = RobotParams().length / 2, RobotParams().width / 2


def test_box_distance_by_hand():
    b = box_rows(np.array([[1.0, 2.0, 2.0, 1.0, 0.0]]))[0]  # x in [0, 2], y in [1.5, 2.5]
    assert box_distance(3.0, 2.0, b) == pytest.approx(1.0)
    assert box_distance(3.0, 3.5, b) == pytest.approx(math.sqrt(2.0))  # to the corner (2, 2.5)
    assert box_distance(1.0, 2.0, b) == pytest.approx(-0.5)  # inside: minus the depth
    turned = box_rows(np.array([[0.0, 0.0, 2.0, 1.0, math.pi / 2]]))[0]  # now 1 m along x, 2 m along y
    assert box_distance(1.5, 0.0, turned) == pytest.approx(1.0)
    assert box_distance(0.0, 1.5, turned) == pytest.approx(0.5)
    assert boxes_distance(0.0, 0.0, np.zeros((0, 6))) == math.inf


@pytest.fixture(scope="module")
def room():
    """A 6 x 5 m room with a desk, a turned table and a pillar."""
    boxes = np.array([[1.5, 0.0, 1.4, 0.7, 0.0], [-1.5, 1.0, 1.6, 0.9, 0.6], [0.0, -1.8, 0.4, 0.4, 0.0]])
    return Room((6.0, 5.0), box_rows(boxes), "test")


def test_field_matches_exact_distances(room):
    rng = np.random.default_rng(0)
    pts = rng.uniform([-3, -2.5], [3, 2.5], (3000, 2))
    exact = np.array([boxes_distance(x, y, room.rows) for x, y in pts])
    near = exact < CAP - CELL
    got = np.array([field_at(room.field, room.x0, room.y0, x, y) for x, y in pts])
    err = got[near] - exact[near]
    # bilinear between exact nodes: outside the boxes too far by at most a quarter cell (near a corner), too near
    # by less than half a cell (where two faces are equally near: the safe side)
    assert err[exact[near] >= 0].max() <= 0.25 * CELL and err.min() >= -0.45 * CELL
    assert np.all(got[~near] >= CAP - 2 * CELL)


def _exact_footprint_clearance(rows, x, y, yaw):
    """Dense outline (1 mm) of the footprint against the exact box distances."""
    c, s = math.cos(yaw), math.sin(yaw)
    t = np.linspace(-1, 1, 2001)
    local = np.concatenate([np.stack([HL * t, np.full_like(t, HW)], 1), np.stack([HL * t, np.full_like(t, -HW)], 1),
                            np.stack([np.full_like(t, HL), HW * t], 1), np.stack([np.full_like(t, -HL), HW * t], 1)])
    pts = local @ np.array([[c, s], [-s, c]]) + [x, y]
    return min(boxes_distance(px, py, rows) for px, py in pts)


def test_footprint_clearance_matches_the_exact_gap(room):
    rng = np.random.default_rng(1)
    checked = 0
    while checked < 60:
        x, y, yaw = rng.uniform(-2.6, 2.6), rng.uniform(-2.2, 2.2), rng.uniform(-math.pi, math.pi)
        exact = _exact_footprint_clearance(room.rows, x, y, yaw)
        if exact > CAP - 0.1 or exact < -0.05:
            continue
        got = obs.footprint_clearance(room.field, room.x0, room.y0, x, y, yaw, HL, HW)
        if exact <= obs.EXACT_BELOW:
            assert got == pytest.approx(exact, abs=0.012), (x, y, yaw)
        else:  # far from everything: a lower bound, itself beyond the exact range
            assert obs.EXACT_BELOW - 0.012 <= got <= exact + 0.012, (x, y, yaw)
        checked += 1
    # a corner touching the desk's face (x = 0.8) from the left, turned 45 deg: the reach is the half diagonal
    reach = math.hypot(HL, HW)
    angle = math.atan2(HW, HL)
    got = obs.footprint_clearance(room.field, room.x0, room.y0, 0.8 - reach - 0.05, 0.0, -angle, HL, HW)
    assert got == pytest.approx(0.05, abs=0.005)


def test_ray_range_to_faces_and_walls(room):
    f, x0, y0 = room.field, room.x0, room.y0
    assert ray_range(True, f, x0, y0, 0.0, 0.0, 1.0, 0.0, 3.0, 6.0, 5.0, 0.0) == pytest.approx(0.8, abs=0.01)  # desk
    assert ray_range(True, f, x0, y0, 0.0, 0.0, 0.0, 1.0, 3.0, 6.0, 5.0, 0.0) == pytest.approx(2.5, abs=0.01)  # wall
    assert ray_range(True, f, x0, y0, 0.0, 0.0, 0.0, -1.0, 3.0, 6.0, 5.0, 0.0) == pytest.approx(1.6, abs=0.01)  # pillar
    # 20 deg up: the ray meets the desk's face (x = 0.8) below its corner, 0.8 / cos(20 deg) away
    ux, uy = math.cos(math.radians(20)), math.sin(math.radians(20))
    assert ray_range(True, f, x0, y0, 0.0, 0.0, ux, uy, 3.0, 6.0, 5.0, 0.0) == pytest.approx(0.8 / ux, abs=0.01)
    assert ray_range(False, f, x0, y0, 0.0, 0.0, 1.0, 0.0, 2.0, 6.0, 5.0, 0.0) == pytest.approx(2.0)  # range limit
    assert ray_range(False, f, x0, y0, 0.0, 0.0, -1.0, 0.0, 5.0, 6.0, 5.0, 0.0) == pytest.approx(3.0)  # walls only


def test_sector_range_sees_what_a_single_ray_misses(room):
    # a 5 cm speckle 1 m away, 5 deg off the ray: the ray passes it, the 7.5 deg half-sector holds it
    a = math.radians(5)
    speck = Room((6.0, 5.0), box_rows(np.array([[math.cos(a), math.sin(a), 0.05, 0.05, 0.0]])), "speck")
    f, x0, y0 = speck.field, speck.x0, speck.y0
    assert ray_range(True, f, x0, y0, 0.0, 0.0, 1.0, 0.0, 3.0, 6.0, 5.0, 0.0) == pytest.approx(3.0)  # the wall
    got = ray_range(True, f, x0, y0, 0.0, 0.0, 1.0, 0.0, 3.0, 6.0, 5.0, math.radians(7.5))
    near = math.hypot(0.971, 0.062)  # the speckle's nearest corner
    assert got == pytest.approx(near, abs=0.03)
    # walls: a wall 2.5 m away seen 80 deg off its normal by a single ray is 2.5 / cos(80 deg) far; the sector
    # reaching 10 deg toward the normal sees it at 2.5 / cos(70 deg)
    ux, uy = math.cos(math.radians(10)), math.sin(math.radians(10))
    assert obs.wall_range(0.0, 0.0, ux, uy, 100.0, 5.0, 0.0) == pytest.approx(2.5 / math.cos(math.radians(80)))
    assert obs.wall_range(0.0, 0.0, ux, uy, 100.0, 5.0, math.radians(10)) == pytest.approx(
        2.5 / math.cos(math.radians(70)))
    assert obs.wall_range(0.0, 0.0, 0.0, 1.0, 6.0, 5.0, 0.2) == pytest.approx(2.5)  # facing the wall
    # a face straight ahead reads its distance, not the cone's first touch short of it
    assert ray_range(True, room.field, room.x0, room.y0, 0.0, 0.0, 1.0, 0.0, 3.0, 6.0, 5.0,
                     math.radians(7.5)) == pytest.approx(0.8, abs=0.01)  # the desk's face


def test_furnished_rooms_are_seeded_and_in_bounds():
    p = FurnitureParams()
    a, b = furnished_room(np.random.default_rng(3), p), furnished_room(np.random.default_rng(3), p)
    assert a.size == b.size and np.array_equal(a.rows, b.rows)
    sizes, counts = [], []
    for seed in range(40):
        r = furnished_room(np.random.default_rng(seed), p)
        sizes += list(r.size)
        counts.append(len(r.rows) / (r.size[0] * r.size[1]))
        centres = np.abs(r.boxes()[:, :2])
        assert np.all(centres <= np.array(r.size) / 2)
    assert p.size_min <= min(sizes) and max(sizes) <= p.size_max
    assert p.density_min - 0.01 <= min(counts) and max(counts) <= p.density_max + 0.01


def test_a_room_too_small_for_the_group_is_no_place_not_a_crash():
    # a 3 x 3 m furnished room cannot hold a group of 5 (it needs ~4 m): NoPlace, so a reset draws another room
    # (it was numpy's "high - low < 0" from deep inside a training run)
    from ssbl_pb.env.rooms.spawn import NoPlace, spawn_layout
    from ssbl_pb.params import SocialParams, WorldParams

    small = Room((3.0, 3.0), box_rows(np.array([[1.2, 1.2, 0.2, 0.2, 0.0]])), "small")
    with pytest.raises(NoPlace, match="too small for a group of 5"):
        spawn_layout(np.random.default_rng(0), WorldParams(), RobotParams(), SocialParams(), 5, "circular", room=small)
