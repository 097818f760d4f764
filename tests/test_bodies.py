"""The simulator's person bodies (``urdf/bodies``, ``env.view.bodies``/``people``): shipped and sized as their
manifest says, drawn where the camera model puts them in their clothes' colours, worn by the members when
``humans.appearance`` is "body", and found by MoveNet."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.env.view.bodies import body_count, body_order
from ssbl_pb.env.view.bullet import pybullet as p
from ssbl_pb.env.view.people import PeopleScene, render_people
from ssbl_pb.env.view.world import World
from ssbl_pb.params import ConfigError, HumansLook, RobotParams, WorldParams, from_dict
from ssbl_pb.perception.camera import sim_camera
from ssbl_pb.urdf import BODY_DIR, body_manifest, body_path


def test_the_shipped_bodies_are_varied_adults_few_triangles_and_small():
    bodies = body_manifest()
    assert 8 <= len(bodies) == body_count() <= 12
    heights = [b["height"] for b in bodies]
    assert min(heights) >= 1.50 and max(heights) <= 1.95 and max(heights) - min(heights) >= 0.3
    assert {b["sex"] for b in bodies} == {"female", "male"} and len({b["build"] for b in bodies}) >= 3
    assert len({b["pose"] for b in bodies}) >= 2
    assert len({tuple(b["colours"]["shirt"]) for b in bodies}) == len(bodies)  # every shirt its own colour
    assert all(b["triangles"] < 5000 for b in bodies)
    assert sum(f.stat().st_size for f in BODY_DIR.iterdir()) < 3e6
    assert "CC0" in (BODY_DIR / "NOTICE").read_text()


@pytest.mark.parametrize("index", [0, 7])
def test_a_body_loads_as_tall_as_its_manifest_says_with_the_proxys_collision_shape(index):
    c = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(body_path(index)), useFixedBase=True, physicsClientId=c)
        lo, hi = p.getAABB(body, -1, physicsClientId=c)
        assert hi[2] == pytest.approx(1.70, abs=0.01)  # the collision shapes: the proxy's 1.70 m (human.urdf)
        parts = p.getVisualShapeData(body, physicsClientId=c)
        assert len(parts) >= 4  # skin, hair, shirt, trousers, shoes: one coloured mesh each
        top = max(_obj_vertices(s[4].decode())[:, 2].max() for s in parts)
        assert top == pytest.approx(body_manifest()[index]["height"], abs=0.005)
    finally:
        p.disconnect(c)


def _obj_vertices(path: str) -> np.ndarray:
    with open(path) as f:
        return np.array([line.split()[1:4] for line in f if line.startswith("v ")], dtype=float)


def test_a_body_is_drawn_in_its_shirts_colour_where_the_camera_model_puts_its_chest():
    index = next(i for i, b in enumerate(body_manifest()) if b["colours"]["shirt"] == [0.8, 0.12, 0.15])
    spec = body_manifest()[index]
    shirt = np.array(spec["colours"]["shirt"])
    robot = RobotParams()
    with PeopleScene() as scene:
        scene.show([[3.0, 0.5, math.pi]], [index])  # facing the robot, 3 m ahead, 0.5 m to its left
        img, _ = scene.render((0.0, 0.0, 0.0), 320, 240)
        scene.show([[3.0, -2.0, math.pi]], [index])  # out of this window
        empty, _ = scene.render((0.0, 0.0, 0.0), 320, 240)
    u, v = sim_camera(robot, 320, 240).robot_to_pixel(np.array([[3.0, 0.5, 0.68 * spec["height"]]]))[0]
    win = (slice(int(v) - 3, int(v) + 4), slice(int(u) - 3, int(u) + 4))

    def shirt_like(rgb: np.ndarray) -> np.ndarray:  # lit shirt: the shirt's colour times a brightness
        rgb = rgb.reshape(-1, 3).astype(float) / 255.0
        k = (rgb @ shirt) / (shirt @ shirt)
        return (np.abs(rgb - k[:, None] * shirt).max(axis=1) < 0.06) & (k > 0.3)

    assert shirt_like(img[win]).mean() > 0.9
    assert shirt_like(empty[win]).mean() == 0.0


def test_members_wear_bodies_chosen_by_the_seed_standing_at_their_pose():
    world = World(WorldParams(humans=HumansLook("body"), n_humans=3, formation="circular"))
    try:
        world.reset(np.random.default_rng(1))
        world.set_body_seed(4)
        world.sync()
        names = [p.getBodyInfo(b, physicsClientId=world.client)[1].decode() for b in world.human_ids[:3]]
        assert names == [f"body_{k:02d}" for k in body_order(4)[:3]]
        assert len(set(names)) == 3
        for i in range(3):
            pos, orn = p.getBasePositionAndOrientation(world.human_ids[i], physicsClientId=world.client)
            assert pos[:2] == pytest.approx(world.group.pos[i], abs=1e-6) and pos[2] == pytest.approx(0.0)
            assert p.getEulerFromQuaternion(orn)[2] == pytest.approx(math.remainder(world.group.yaw[i], 2 * math.pi))
        shown = set(world.human_ids[:3])
        parked = [b for b in world._bodies if b not in shown]
        assert all(p.getBasePositionAndOrientation(b, physicsClientId=world.client)[0][2] < -5 for b in parked)
        world.set_body_seed(5)
        world.sync()
        assert body_order(5)[:3] != body_order(4)[:3]
        assert [p.getBodyInfo(b, physicsClientId=world.client)[1].decode() for b in world.human_ids[:3]] == \
            [f"body_{k:02d}" for k in body_order(5)[:3]]
        # the engine's contacts and PyBullet's agree with bodies too (their collision shapes are the proxy's)
        world.base.pose = np.array([*(world.group.pos[0] - [0.45, 0.0]), 0.0])
        world.invalidate()
        assert ("human", 0) in {(c.kind, c.index) for c in world.collisions()}
        assert ("human", 0) in {(c.kind, c.index) for c in world.pybullet_contacts()}
    finally:
        world.close()


def test_the_appearance_switch_names_its_field():
    with pytest.raises(ConfigError, match=r"humans\.appearance = 'mesh': expected one of \('proxy', 'body'\)"):
        from_dict(WorldParams, {"humans": {"appearance": "mesh"}}, "world")
    with pytest.raises(ConfigError, match=r"world\.humans = 'body': expected a mapping"):
        from_dict(WorldParams, {"humans": "body"}, "world")
    assert WorldParams().humans.appearance == "proxy"  # training and the figures keep the proxies


def test_eight_people_render_in_one_frame_each_in_sight():
    people = [[4.0, y, math.pi] for y in np.linspace(-1.6, 1.6, 8)]
    with PeopleScene() as scene:
        ids = scene.show(people)  # eight people: the ten bodies' first eight for seed 0
        _, mask = scene.render((0.0, 0.0, 0.0), 320, 240, segmentation=True)
    assert len(set(ids)) == 8
    assert all((mask == b).sum() > 100 for b in ids)
    img = render_people(people[:2], size=(160, 120))
    assert img.shape == (120, 160, 3)


def test_movenet_finds_a_body_facing_the_robot_at_2_5_m_in_a_qvga_frame():
    pytest.importorskip("ai_edge_litert")
    from ssbl_pb.bench.body_detection import best_score, mask_box, movenet_detector
    from ssbl_pb.perception.tracking.tuning import MOVENET_DEFAULT

    with PeopleScene() as scene:
        (pid,) = scene.show([[2.5, 0.0, math.pi]], [0])
        img, mask = scene.render((0.0, 0.0, 0.0), 320, 240, segmentation=True)
    truth, _ = mask_box(mask, pid)
    score = best_score(movenet_detector()(img), truth)
    assert score > MOVENET_DEFAULT.trk.birth_score  # a box there, strong enough to start a track


def test_the_virtual_pepper_shows_bodies_and_names_movenet_for_them(tmp_path):
    pytest.importorskip("qi")
    from ssbl_pb.bench.deploy import virtual_pepper
    from ssbl_pb.deploy.naoqi import NaoqiRobot
    from ssbl_pb.deploy.perceive import detector_for

    # seed 35: the group in view from the start
    with virtual_pepper(tmp_path / "vp.jsonl", 35, "default", "--appearance", "body") as (_, url):
        robot = NaoqiRobot(url, RobotParams())
        try:
            assert robot.identity["detector"] == "movenet" and detector_for("auto", robot) == "movenet"
        finally:
            robot.close()


def test_the_lockstep_robot_draws_bodies_when_asked_and_movenet_ranges_them():
    """``SimRobot(appearance="body")`` (the bench's lockstep runs) renders the members as bodies in its own frames,
    names MoveNet for them as the virtual Pepper does, and deploy's MoveNet chain places each member seen whole
    near where they stand; with box proxies it names the colour detector."""
    pytest.importorskip("ai_edge_litert")
    from ssbl_pb.deploy.perceive import detector_for, make_detector
    from ssbl_pb.deploy.robot import relative
    from ssbl_pb.virtual.robot import SimRobot

    robot = SimRobot("default", 41, appearance="body")
    try:
        assert detector_for("auto", robot) == "movenet" and robot.world.human_ids[0] in robot.world._bodies
        w = robot.world
        (x, y, _), (cx, cy) = w.robot_pose, w.group.centre
        w.base.pose = np.array([x, y, math.atan2(cy - y, cx - x)])  # turned to the group: both members in view
        w.invalidate()
        img = robot.render().image
        detect, torso = make_detector("movenet")
        boxes = detect(img)
        xy = detect.ground(sim_camera(RobotParams(), *robot.image_size))
        truth = np.array([relative(robot.world.robot_pose, [*m, 0.0])[:2] for m in robot.world.group.pos])
    finally:
        robot.close()
    assert not torso and len(boxes) == len(truth) == 2
    err = np.hypot(*(xy[:, None] - truth[None]).transpose(2, 0, 1)).min(axis=1)  # each found person to a member
    assert err.max() < 0.7, (xy, truth)
    proxies = SimRobot("default", 35)
    try:
        assert detector_for("auto", proxies) == "colour"
    finally:
        proxies.close()


def test_deploys_movenet_chain_ranges_members_within_the_lasers_reach_by_their_returns():
    """Deploy's perception on the virtual Pepper's bodies (MoveNet): the members 1.5-3 m ahead, each placed by the
    lasers' nearest return and the depth the virtual Pepper names (its people's 0.28 m cylinder), within 0.06 m of
    where they stand; without the lasers' returns (keypoints only) farther off."""
    pytest.importorskip("ai_edge_litert")
    from ssbl_pb.deploy.perceive import Perception
    from ssbl_pb.deploy.robot import relative
    from ssbl_pb.perception.groups.estimate import TRACKER_KEYPOINTS
    from ssbl_pb.virtual.robot import SimClock, SimRobot

    robot = SimRobot("default", 41, appearance="body")
    try:
        w = robot.world
        (cx, cy), (x, y, _) = w.group.centre, w.robot_pose
        yaw = math.atan2(cy - y, cx - x)
        w.base.pose = np.array([cx - 2.2 * math.cos(yaw), cy - 2.2 * math.sin(yaw), yaw])  # 2.2 m from the centre
        w.invalidate()
        clock = SimClock(robot)
        errors = {}
        for lasers in (True, False):
            perception = Perception(robot, clock.now, "movenet", RobotParams(), threaded=False)
            assert perception.laser_depth == pytest.approx(0.28) and not perception.torso
            for _ in range(4):  # three hits confirm a keypoint track (``TRACKER_KEYPOINTS``)
                clock.sleep(0.1)
                robot.render()
                odo = robot.odometry()
                perception.odometry.append((odo.stamp, odo.pose))
                if lasers:
                    scan = robot.ranges()
                    perception.ranges(scan.points[:len(scan.points) - scan.sonars], odo.pose)
                perception.step()
            est, _ = perception.snapshot()
            assert perception._group.tracker.params is TRACKER_KEYPOINTS  # MoveNet's tracks (colour's: TRACKER)
            start = robot.start_pose
            truth = np.array([relative(start, [*m, 0.0])[:2] for m in w.group.pos])  # odometry frame
            found = np.array([m.pos for m in est.members])
            errors[lasers] = np.hypot(*(found[:, None] - truth[None]).transpose(2, 0, 1)).min(axis=0)
    finally:
        robot.close()
    assert len(errors[True]) == 2 and errors[True].max() < 0.06, errors  # measured 0.02 and 0.04
    assert errors[False].max() > 2 * errors[True].max(), errors  # measured 0.22 and 0.16


def test_the_body_pose_table_gives_median_facing_error_its_share_within_45_deg_and_median_range_error():
    from ssbl_pb.bench.body_pose import markdown

    rows = [{"body": b, "distance": 2.0, "view": v, "facing_error_deg": f, "range_error": e}
            for v in ("front", "side", "back")
            for b, (f, e) in enumerate([(10.0, 0.1), (-170.0, 0.3), (20.0, math.nan)])]
    text = markdown(rows)
    # |10|, |-170|, |20| -> median 20 deg, 2 of 3 within 45 deg; range errors 0.1 and 0.3 -> median +0.20 m
    assert "| front | 20 deg, 67%; +0.20 m |" in text and "| back | 20 deg, 67%; +0.20 m |" in text
