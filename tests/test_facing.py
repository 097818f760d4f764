"""Facing from the virtual Pepper's frames (perception/detection/facing.py): the convention, the geometry on synthetic
frames, rendered people facing the camera, away from it and partly hidden, and deploy's detector exposing it."""

import math

import cv2
import numpy as np
import pytest

from ssbl_pb.bench.facing import place
from ssbl_pb.deploy.perceive import make_detector
from ssbl_pb.env.view.world import World
from ssbl_pb.params import RobotParams
from ssbl_pb.perception.camera import sim_camera
from ssbl_pb.perception.detection.facing import facing_yaw, phi_of, wrap
from ssbl_pb.perception.detection.proxy_facing import ProxyBody, estimate_facing
from ssbl_pb.urdf import HUMAN_COLOURS

CAM = sim_camera(RobotParams(), 320, 240)


@pytest.fixture(scope="module")
def world():
    w = World()
    w.reset(np.random.default_rng(0), n_humans=3)
    yield w
    w.close()


def err_deg(est: float, true_deg: float) -> float:
    return abs(math.degrees(float(wrap(est - math.radians(true_deg)))))


def render(world, heading: float, people: list[tuple[int, float, float, float]]):
    """Frame, the colour detector's boxes and its facing; ``people``: (member, distance, bearing, phi deg)."""
    place(world, heading, [(m, d, b, math.radians(p)) for m, d, b, p in people])
    rgb, _ = world.render_first_person(320, 240)
    detect, _ = make_detector("colour")
    boxes = detect(rgb)
    return rgb, boxes, detect.last_colours, detect.facing()


def row_of(colours: np.ndarray, member: int) -> int:
    (i,) = np.flatnonzero(colours == member)
    return int(i)


# -- the convention ---------------------------------------------------------------------------------------------
def test_convention_by_hand():
    cam = (0.0, 0.0)
    assert phi_of((2.0, 0.0), math.pi, cam) == pytest.approx(0.0)  # looks at the camera
    assert abs(phi_of((2.0, 0.0), 0.0, cam)) == pytest.approx(math.pi)  # back to it
    # facing -x and turned counter-clockwise (seen from above) by 0.5 rad: to the person's own left, which is the
    # camera's right (-y): phi = +0.5
    assert phi_of((2.0, 0.0), math.pi + 0.5, cam) == pytest.approx(0.5)
    assert phi_of((0.0, 2.0), -math.pi / 2 - 0.3, cam) == pytest.approx(-0.3)  # same off the optical axis
    xy = np.array([[2.0, 1.0], [3.0, -2.0]])
    yaw = np.array([2.0, -0.4])
    phi = [phi_of(p, y, (0.05, 0.0)) for p, y in zip(xy, yaw, strict=True)]
    assert facing_yaw(xy, np.array(phi)) == pytest.approx(yaw)


# -- geometry on synthetic frames -------------------------------------------------------------------------------
def draw(xy: tuple[float, float], yaw: float, shades: tuple[float, float, float, float]) -> np.ndarray:
    """A QVGA frame of the proxy's torso (green, HUMAN_COLOURS[0]; faces front, left, back, right shaded by
    ``shades``) and chest plate (its front face) at robot-frame ``xy`` facing ``yaw``, through the pinhole: a pixel
    takes a face's colour when its centre (integer coordinates, as TinyRenderer samples) falls inside; grey
    background."""
    body = ProxyBody()
    img = np.full((240, 320, 3), 128, np.uint8)
    f = np.array([math.cos(yaw), math.sin(yaw)])
    left = np.array([-f[1], f[0]])
    a, b = body.torso_half
    c = CAM.centre()[:2]

    def fill(corners: list[tuple[float, float]], zs: tuple[float, float], rgb: np.ndarray) -> None:
        pts = [np.array(xy) + x * f + y * left for x, y in corners]
        quad = [(*pts[0], zs[0]), (*pts[1], zs[0]), (*pts[1], zs[1]), (*pts[0], zs[1])]
        uv = CAM.robot_to_pixel(np.array(quad))
        # the pixels whose centres (integer coordinates) the quad covers: on the same side of its four edges
        cols, rows = np.meshgrid(np.arange(320), np.arange(240))
        cross = [(q[0] - p[0]) * (rows - p[1]) - (q[1] - p[1]) * (cols - p[0])
                 for p, q in zip(uv, np.roll(uv, -1, 0), strict=True)]
        inside = np.all(np.array(cross) >= 0, axis=0) | np.all(np.array(cross) <= 0, axis=0)
        img[inside] = np.round(rgb).astype(np.uint8)

    base = np.array(HUMAN_COLOURS[0][:3]) * 255
    faces = [((a, b), (a, -b), (1, 0)), ((-a, b), (a, b), (0, 1)), ((-a, -b), (-a, b), (-1, 0)),
             ((a, -b), (-a, -b), (0, -1))]
    for (p, q, n), shade in zip(faces, shades, strict=True):
        normal = n[0] * f + n[1] * left
        mid = np.array(xy) + 0.5 * ((p[0] + q[0]) * f + (p[1] + q[1]) * left)
        if normal @ (c - mid) > 0:
            fill([p, q], body.torso_z, base * shade)
    plate = np.array(xy) + body.marker_x[1] * f
    if f @ (c - plate) > 0:
        w = body.marker_half_width
        fill([(body.marker_x[1], w), (body.marker_x[1], -w)], body.marker_z, np.array([0.95, 0.85, 0.10]) * 255)
    return img


def test_geometry_on_synthetic_frames():
    # faces shaded apart (a crease shows where two meet); side-on views (80-100 deg) are left to the rendered
    # tests: draw() shows the plate's front only, TinyRenderer also its 0.015 m proud side
    xy = (3.0, 0.4)
    a, b = ProxyBody().torso_half
    for phi_deg in range(-180, 180, 10):
        if 80 <= abs(phi_deg) <= 100:
            continue
        yaw = math.atan2(CAM.centre()[1] - xy[1], CAM.centre()[0] - xy[0]) + math.radians(phi_deg)
        img = draw(xy, yaw, (1.0, 0.8, 0.9, 0.7))
        detect, _ = make_detector("colour")
        assert len(detect(img)) == 1
        fac = detect.facing()
        front = abs(phi_deg) < 90
        assert (fac.front[0] > 0.5) == front and fac.marker[0] == front, phi_deg
        err = err_deg(fac.phi[0], phi_deg)
        if front:
            assert err < 4.0 and fac.std[0] < math.radians(5), (phi_deg, err)
        elif math.isnan(fac.phi[0]):  # a back seen square-on, or where both faces span alike (~120 deg)
            assert abs(phi_deg) >= 170 or 110 <= abs(phi_deg) <= 130, phi_deg
        else:
            assert math.radians(err) <= 2.5 * fac.std[0], (phi_deg, err)
        if fac.std[0] < math.radians(5):
            # the axis behind the box's ground point along the line of sight: deploy's torso_depth, a |cos| + b |sin|
            # of the facing's angle to the optical axis (the rows see the corner least deep along it), stretched
            # onto the line of sight
            psi = yaw - math.pi
            bearing = math.atan2(xy[1] - CAM.centre()[1], xy[0] - CAM.centre()[0])
            depth = (a * abs(math.cos(psi)) + b * abs(math.sin(psi))) / math.cos(bearing)
            assert fac.depth[0] == pytest.approx(depth, abs=0.01), phi_deg


def test_a_back_without_a_crease_is_mirror_ambiguous():
    # faces shaded alike: the width gives |phi| (folded), not the side the person turned to
    xy = (3.0, 0.0)
    phi = math.radians(155)
    img = draw(xy, math.atan2(-xy[1], CAM.centre()[0] - xy[0]) + phi, (1.0, 1.0, 1.0, 1.0))
    fac = estimate_facing(img, make_detector("colour")[0](img))
    assert fac.front[0] < 0.01
    assert abs(fac.phi[0]) > math.radians(165) or math.isnan(fac.phi[0])  # the two modes' mean: about pi
    left, right = fac.posterior[0][fac.grid > 0].sum(), fac.posterior[0][fac.grid < 0].sum()
    assert left == pytest.approx(right, abs=0.2)
    assert fac.phi_abs[0] > math.radians(120)


# -- rendered frames --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("distance", [2.0, 4.0])
def test_front_facing_within_tolerance(world, distance):
    rng = np.random.default_rng(int(distance))
    room = math.radians(RobotParams().camera_hfov_deg) / 2 - math.atan2(0.3, distance) - 0.02
    for phi_deg in (-75, -45, -20, 0, 15, 40, 70):
        _, boxes, colours, fac = render(world, rng.uniform(-3, 3), [(0, distance, rng.uniform(-room, room), phi_deg)])
        i = row_of(colours, 0)
        # measured (tools/bench_facing.py): median 0.5-1 deg, p90 1.3-2.2 deg
        assert err_deg(fac.phi[i], phi_deg) < 5.0, (phi_deg, math.degrees(fac.phi[i]))
        assert fac.std[i] < math.radians(5) and fac.front[i] > 0.99 and fac.marker[i]


@pytest.mark.parametrize("phi_deg", [180, 150, -130, 110, -165])
def test_back_facing_is_told_from_front(world, phi_deg):
    for heading in (0.3, 2.2, -1.9):
        _, _, colours, fac = render(world, heading, [(1, 3.0, 0.1, phi_deg)])
        i = row_of(colours, 1)
        assert fac.front[i] < 0.05 and not fac.marker[i]
        assert fac.phi_abs[i] > math.radians(95)
        # with a crease between the faces seen the sign is known; without, phi is the mirror pair's mean (pi) or
        # NaN: either way |phi| > 90 deg and the error within 2.5 of the spread it reports
        if not math.isnan(fac.phi[i]):
            assert abs(fac.phi[i]) > math.radians(90)
            assert math.radians(err_deg(fac.phi[i], phi_deg)) <= 2.5 * fac.std[i]


@pytest.mark.parametrize("phi_deg", [115, -115, 128, -128])
def test_a_back_near_side_on_keeps_its_sign(world, phi_deg):
    # the nose beside the head (seen to ~135 deg off the line of sight) and the crease between the faces tell a
    # back turned left from one turned right, whatever the faces' shading (the robot's heading)
    for heading in (0.3, 2.2, -1.9, 1.0):
        for distance in (2.0, 4.0):
            _, _, colours, fac = render(world, heading, [(1, distance, 0.1, phi_deg)])
            i = row_of(colours, 1)
            assert err_deg(fac.phi[i], phi_deg) < 5.0, (heading, distance, math.degrees(fac.phi[i]))


def test_sign_a_person_turned_to_their_left_vs_right(world):
    # robot at a known place; the person 3 m straight ahead; checked against the frame: the chest plate (yellow)
    # lies right of the torso box's middle when they turn to their own left (phi > 0), left when to their right
    for phi_deg, side in ((40, 1), (-40, -1)):
        rgb, boxes, colours, fac = render(world, 0.0, [(0, 3.0, 0.0, phi_deg)])
        i = row_of(colours, 0)
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        ys, xs = np.nonzero((np.abs(hsv[..., 0].astype(int) - 26) <= 3) & (hsv[..., 1] > 90))
        x, y, w, h = boxes[i, :4]
        inside = (ys >= y) & (ys < y + h)
        assert np.sign(xs[inside].mean() - (x + w / 2)) == side
        assert err_deg(fac.phi[i], phi_deg) < 5.0
        # and in the world: their facing yaw from their robot-frame position
        truth = world.group.yaw[0] - world.base.pose[2]
        rel = world.group.pos[0] - world.base.pose[:2]
        assert facing_yaw(rel[None], fac.phi[i:i + 1])[0] == pytest.approx(wrap(truth), abs=math.radians(5))


def test_a_partly_hidden_person(world):
    # the nearer person (2 m, facing 20 deg) hides about half of the farther one (3.5 m)
    near_w, far_w = math.atan2(0.23, 2.0), math.atan2(0.23, 3.5)
    for far_phi, plate_shows in ((-35, True), (35, False)):
        # the farther one stands to the near one's left (image left): turned to their right (phi < 0) their plate
        # moves to the image's left, away from the nearer person
        _, boxes, colours, fac = render(world, 0.7, [(0, 2.0, 0.0, 20), (2, 3.5, near_w + 0.1 * far_w, far_phi)])
        near, far = row_of(colours, 0), row_of(colours, 2)
        assert err_deg(fac.phi[near], 20) < 5.0
        assert fac.marker[far] == plate_shows
        if plate_shows:
            assert err_deg(fac.phi[far], far_phi) < 6.0
        else:  # hidden: no claim that the front is turned away, and no confident wrong answer
            assert fac.front[far] > 0.05
            assert math.isnan(fac.phi[far]) or math.radians(err_deg(fac.phi[far], far_phi)) <= 2.5 * fac.std[far]


def test_a_person_cut_by_the_image_side_beside_a_nearer_one(world):
    # the farther one stands against the nearer one's right edge and is cut by the image's side; their plate
    # touches the nearer one's box: it is not the nearer one's, whether or not the cut box is passed (deploy drops
    # boxes cut by the side), and the cut one, with neither edge its own, gets no confident wrong answer
    near_w = math.atan2(0.23, 2.9)
    rgb, boxes, colours, fac = render(world, 0.5, [(0, 2.9, -0.36, -67), (2, 3.6, -0.36 - near_w - 0.04, -50)])
    near, far = row_of(colours, 0), row_of(colours, 2)
    assert boxes[far, 0] + boxes[far, 2] >= 319  # cut
    alone = estimate_facing(rgb, boxes[near:near + 1], colours=colours[near:near + 1])
    assert err_deg(fac.phi[near], -67) < 5.0 and err_deg(alone.phi[0], -67) < 5.0
    assert math.isnan(fac.phi[far]) or math.radians(err_deg(fac.phi[far], -50)) <= 2.5 * fac.std[far]


def test_the_detector_exposes_the_facing_of_its_boxes(world):
    detect, torso = make_detector("colour")
    with pytest.raises(RuntimeError):
        detect.facing()
    assert len(detect(np.full((240, 320, 3), 128, np.uint8))) == 0
    empty = detect.facing()
    assert empty.phi.shape == (0,) and empty.posterior.shape[0] == 0
    _, boxes, colours, fac = render(world, 1.0, [(0, 2.5, -0.15, 30), (1, 3.0, 0.2, -120)])
    assert fac.phi.shape == (len(boxes),) == colours.shape and sorted(colours.tolist()) == [0, 1]
    assert err_deg(fac.phi[row_of(colours, 0)], 30) < 5.0
    assert fac.posterior.shape == (len(boxes), len(fac.grid)) and np.allclose(fac.posterior.sum(axis=1), 1.0)
