"""The PyBullet world: seeded spawning, base limits, collisions, cameras, bad configuration."""

import math

import numpy as np
import pytest

from ssbl_pb.core.base import HolonomicBase
from ssbl_pb.env.view.world import World
from ssbl_pb.params import ConfigError, RobotParams, SocialParams, WorldParams


@pytest.fixture(scope="module")
def world():
    w = World()
    yield w
    w.close()


def test_same_seed_same_episode(world):
    world.reset(np.random.default_rng(7), n_humans=3, formation="circular")
    a = (world.robot_pose.copy(), world.group.pos.copy())
    world.reset(np.random.default_rng(8), n_humans=3, formation="circular")
    world.reset(np.random.default_rng(7), n_humans=3, formation="circular")
    assert np.array_equal(a[0], world.robot_pose) and np.array_equal(a[1], world.group.pos)


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_spawn_inside_walls_and_outside_group(world, n):
    for seed in range(20):
        world.reset(np.random.default_rng(seed), n_humans=n)
        half = np.array(world.params.room_size) / 2
        assert np.all(np.abs(world.group.pos) < half - SocialParams().human_radius)
        assert np.all(world.wall_clearance() > 0)
        d = math.hypot(*(world.robot_pose[:2] - world.group.centre0))
        assert world.params.robot_spawn_min <= d <= world.params.robot_spawn_max
        assert not world.collisions()


def test_behind_start_is_behind_a_member(world):
    world.reset(np.random.default_rng(3), start="behind")
    r = world.robot_pose[:2] - world.group.centre0
    ang = np.arctan2(*(world.group.pos - world.group.centre0).T[::-1])
    diff = np.abs(np.angle(np.exp(1j * (ang - math.atan2(r[1], r[0])))))
    assert diff.min() <= 0.3 + 1e-9


def test_base_respects_speed_and_acceleration_limits():
    rp = RobotParams()
    base = HolonomicBase(rp, 0.1)
    base.reset(np.zeros(3))
    speeds, prev = [], np.zeros(3)
    for i in range(60):
        base.step(np.array([5.0, 5.0, 0.0]) if i < 30 else np.array([0.0, 0.0, 9.0]))
        if i == 29:
            assert max(speeds) == pytest.approx(rp.max_speed)
        dv = math.hypot(*(base.vel[:2] - prev[:2]))
        assert dv <= rp.max_accel * 0.1 + 1e-12
        assert abs(base.vel[2] - prev[2]) <= rp.max_yaw_accel * 0.1 + 1e-12
        prev = base.vel.copy()
        speeds.append(math.hypot(*base.vel[:2]))
    assert abs(base.vel[2]) == pytest.approx(rp.max_yaw_rate)


def test_base_latency_delays_the_command():
    base = HolonomicBase(RobotParams(latency_s=0.3), 0.1)
    base.reset(np.zeros(3))
    for _ in range(3):
        base.step(np.array([0.3, 0, 0]))
        assert base.vel[0] == 0.0
    base.step(np.array([0.3, 0, 0]))
    assert base.vel[0] > 0


def test_collisions_agree_with_pybullet(world):
    world.reset(np.random.default_rng(0), n_humans=2)
    member = world.group.pos[0]
    for dist in (0.9, 0.6, 0.5, 0.45, 0.3):  # robot centre to member centre along the robot's x axis
        world.base.pose = np.array([member[0] - dist, member[1], 0.0])
        world._synced = False
        ours = {(c.kind, c.index) for c in world.collisions()}
        theirs = {(c.kind, c.index) for c in world.pybullet_contacts()}
        assert (("human", 0) in ours) == (dist < 0.24 + 0.28), dist
        assert ours == theirs, dist
        assert world.in_contact() == bool(ours), dist
    half = world.params.room_size[0] / 2
    world.base.pose = np.array([half - 0.2, 0.0, 0.0])
    world._synced = False
    assert ("wall", 0) in {(c.kind, c.index) for c in world.collisions()}
    assert ("wall", 0) in {(c.kind, c.index) for c in world.pybullet_contacts()}


def test_first_person_camera_sees_the_group(world):
    world.reset(np.random.default_rng(1), n_humans=2)
    g = world.group.centre0 - world.robot_pose[:2]
    world.base.pose = np.array([*world.robot_pose[:2], math.atan2(g[1], g[0])])
    world._synced = False
    rgb, seg = world.render_first_person(84, 84, segmentation=True)
    assert rgb.shape == (84, 84, 3) and rgb.dtype == np.uint8
    assert any(np.any(seg == hid) for hid in world.human_ids[:2])
    world.base.pose[2] += math.pi  # facing away: no member in view
    world._synced = False
    _, seg = world.render_first_person(84, 84, segmentation=True)
    assert not any(np.any(seg == hid) for hid in world.human_ids[:2])


def test_top_down_pixel_mapping(world):
    world.reset(np.random.default_rng(2))
    cam = world.top_down_camera(200)
    img = world.render_top_down(cam)
    assert img.shape == (cam.height, cam.width, 3)
    u, v = cam.to_pixel(world.group.pos[0]).astype(int)
    floor = np.array([0.78, 0.76, 0.72]) * 255
    assert np.abs(img[v, u].astype(float) - floor).sum() > 60  # a member is drawn there, not bare floor


@pytest.mark.parametrize("kwargs,field", [
    ({"room_size": (4.0, 4.0), "n_humans": 5}, "room_size"),
    ({"n_humans": 1}, "n_humans"),
    ({"n_humans": 50}, "n_humans"),
    ({"room_size": (10.0, -1.0)}, "room_size"),
    ({"formation": "blob"}, "formation"),
])
def test_bad_world_config(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        WorldParams(**kwargs).check_fits(SocialParams())


def test_negative_radius_rejected():
    with pytest.raises(ConfigError, match="personal_radius"):
        SocialParams(personal_radius=-1.0)


def test_fractional_latency_blends_commands():
    base = HolonomicBase(RobotParams(latency_s=0.15, max_accel=100.0), 0.1)
    base.reset(np.zeros(3))
    base.step(np.array([0.2, 0, 0]))
    assert base.vel[0] == 0.0
    base.step(np.array([0.2, 0, 0]))  # 1.5 periods late: half of the first command is active
    assert base.vel[0] == pytest.approx(0.1)
    base.step(np.array([0.2, 0, 0]))
    assert base.vel[0] == pytest.approx(0.2)


def test_bodies_stand_on_the_floor(world):
    import pybullet as p

    world.reset(np.random.default_rng(5))
    world.sync()

    def top_and_bottom(body):
        boxes = [p.getAABB(body, link, physicsClientId=world.client)
                 for link in range(-1, p.getNumJoints(body, physicsClientId=world.client))]
        return max(b[1][2] for b in boxes), min(b[0][2] for b in boxes)

    top, bottom = top_and_bottom(world.robot_id)
    assert top == pytest.approx(1.21, abs=0.03) and bottom == pytest.approx(0.0, abs=0.02)
    top, bottom = top_and_bottom(world.human_ids[0])
    assert top == pytest.approx(1.70, abs=0.03) and bottom == pytest.approx(0.0, abs=0.02)
