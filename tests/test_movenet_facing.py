"""Facing from MoveNet's keypoints where it is used: each track's in the PETS pipeline (GroundTracker,
tools/track.py's ``facing_deg``), deploy's group model on a robot, and the PETS facing benchmark's scoring
(ssbl_pb/bench/pets_facing)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from ssbl_pb.params import RobotParams
from ssbl_pb.perception.detection.keypoints import BodyParams, silhouette
from ssbl_pb.perception.detection.movenet import people

ROOT = Path(__file__).resolve().parents[1]
PETS = ROOT.parent / "shared" / "data" / "video" / "pets2009_s2l1"
CALIB = PETS / "View_001_tsai_calibration.xml"
VIDEO = PETS / "vtest.avi"
P = BodyParams()


def person_row(geom: object, xy: np.ndarray, yaw: float, face: float = 0.9) -> np.ndarray:
    """A people row (``movenet.people``) of a person at ground point ``xy`` facing ``yaw``: the template's points
    (``BodyParams``; the shoulders and hips on the ``silhouette`` the camera sees) projected by ``geom``, scores
    0.9 (the face's ``face``), and a box from the head top to the feet, 0.45 m wide."""
    cam = np.asarray(geom.centre_m, dtype=float)[:2]
    u = (xy - cam) / np.hypot(*(xy - cam))
    view = np.array([[math.cos(yaw) * u[0] + math.sin(yaw) * u[1], -math.sin(yaw) * u[0] + math.cos(yaw) * u[1]]])
    pts = np.full((17, 3), np.nan)
    pts[0] = P.nose
    pts[[1, 3]] = P.eye, P.ear
    pts[[2, 4]] = [P.eye[0], -P.eye[1], P.eye[2]], [P.ear[0], -P.ear[1], P.ear[2]]
    for (left, right), part, depth in (((5, 6), P.shoulder, P.torso_depth[0]), ((11, 12), P.hip, P.torso_depth[1])):
        edges = silhouette(view, part[1], depth)[0] + [part[0], 0.0]
        pts[left], pts[right] = (*edges[0], part[2]), (*edges[1], part[2])
    c, s = math.cos(yaw), math.sin(yaw)
    world = np.column_stack([xy[0] + c * pts[:, 0] - s * pts[:, 1], xy[1] + s * pts[:, 0] + c * pts[:, 1], pts[:, 2]])
    kp = np.zeros((17, 3))
    ok = np.isfinite(world).all(axis=1)
    kp[ok, :2] = geom.world_to_image(world[ok])
    kp[ok, 2] = 0.9
    kp[[0, 1, 2], 2] = face
    foot = geom.world_to_image(np.array([[*xy, 0.0]]))[0]
    top = geom.world_to_image(np.array([[*xy, 1.76]]))[0]
    w = 0.45 * (foot[1] - top[1]) / 1.76
    return people(np.array([[foot[0] - w / 2, top[1], w, foot[1] - top[1], 0.6]]), kp[None])[0]


@pytest.mark.skipif(not CALIB.is_file(), reason=f"PETS calibration not found: {CALIB}")
def movenet_deploy(rows: np.ndarray, frames: int = 6, returns: np.ndarray | None = None) -> list:
    """Deploy's perception with MoveNet's detector, its network replaced by one that returns ``rows``, over
    ``frames`` black frames 0.1 s apart at the odometry origin (with ``returns``: these laser returns each frame);
    the members it then knows."""
    from ssbl_pb.deploy.perceive import Perception
    from ssbl_pb.deploy.robot import Frame
    from ssbl_pb.perception.detection.movenet import MoveNetFacing
    from ssbl_pb.perception.tracking.tuning import MOVENET_DEFAULT

    class Robot:
        stamp = 0.0

        def frame(self) -> Frame:
            self.stamp += 0.1
            return Frame(np.zeros((240, 320, 3), np.uint8), self.stamp)

    clock = [0.0]
    perception = Perception(Robot(), lambda: clock[0], "colour", RobotParams(), threaded=False)
    perception.detect, perception.torso = MoveNetFacing(MOVENET_DEFAULT.ssd, MOVENET_DEFAULT.rng,
                                                        detector=lambda frame: rows.copy()), False
    for _ in range(frames):
        clock[0] += 0.1
        perception.odometry.append((clock[0], np.zeros(3)))
        if returns is not None:
            perception.ranges(returns, np.zeros(3))
        perception.step()
    return perception.snapshot()[0].members


def test_a_track_faces_where_the_body_faces_not_where_it_moves():
    # PETS' camera, two people 1 m/s across the square: one walks forward (faces +x, moves +x), one backwards
    # (faces +x, moves -x). Each track's facing is +x; its velocity says otherwise for the second
    from ssbl_pb.perception.datasets.tsai import TsaiCamera
    from ssbl_pb.perception.detection.ranging import TsaiGeometry
    from ssbl_pb.perception.tracking.pipeline import GroundTracker
    from ssbl_pb.perception.tracking.tuning import default_params

    cam = TsaiCamera.from_xml(CALIB)
    geom, pp = TsaiGeometry(cam), default_params("movenet")
    gt = GroundTracker(cam, pp.trk, pp.box, pp.rng)
    for k in range(21):
        a, b = np.array([-6.0 + k / 7, 0.0]), np.array([2.0 - k / 7, -4.0])
        tracks = gt.step(np.stack([person_row(geom, a, 0.0), person_row(geom, b, 0.0)]), 1 / 7)
    assert len(tracks) == 2
    for tid, _, xy, v in tracks:
        yaw, std = gt.facing_of(tid)
        assert abs(math.degrees(yaw)) < 15 and std < math.radians(40), (xy, yaw)
        assert abs(abs(math.degrees(math.atan2(v[1], v[0]))) - (0 if xy[1] > -2 else 180)) < 20  # its motion
    # close looks go first to the tracks never looked at (the lowest id first), then to the other one
    rows = np.stack([person_row(geom, xy, 0.0) for _, _, xy, _ in tracks])
    first = gt.choose_looks(rows, count=1)
    assert len(first) == 1 and first[0][0] == min(t for t, *_ in tracks)
    gt.look([(first[0][0], rows[first[0][1], 5:].reshape(17, 3))])
    assert gt.choose_looks(rows, count=2)[0][0] == max(t for t, *_ in tracks)
    assert gt.choose_looks(rows, max_height=1.0) == []  # everyone too tall for a look to help
    # a close look (``GroundTracker.look``) of the backward walker turned about: the track follows over some looks
    tid, xy = next((t, xy) for t, _, xy, _ in tracks if xy[1] < -2)
    for _ in range(4):
        gt.look([(tid, person_row(geom, xy, math.pi)[5:].reshape(17, 3))])
    assert abs(abs(math.degrees(gt.facing_of(tid)[0])) - 180) < 30


@pytest.mark.skipif(not VIDEO.is_file(), reason=f"PETS video not found: {VIDEO}")
def test_track_writes_each_tracks_facing(tmp_path):
    import importlib.util

    from ssbl_pb.perception.tracking.tracking_io import WORLD_HEADER, load_tracks, read_world

    spec = importlib.util.spec_from_file_location("track", ROOT / "tools" / "track.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    cv2.setNumThreads(1)
    out = tmp_path / "t"
    assert tool.main([str(VIDEO), "--calib", str(CALIB), "--out", str(out), "--start", "400", "--stop", "414",
                      "--fps", "7", "--no-overlay", "--quiet"]) == 0
    text = (out / "tracks_world.csv").read_text().splitlines()
    assert text[0] == WORLD_HEADER == "frame,id,x_m,y_m,vx,vy,facing_deg"
    w = read_world(out / "tracks_world.csv")
    known = w[np.isfinite(w[:, 6])]
    assert len(known) >= 10 and (np.abs(known[:, 6]) <= 180).all()
    assert len(load_tracks(out)) == len(w)  # eval_tracking reads it as before


def test_deploy_feeds_movenet_facing_to_the_group_model():
    # deploy's pipeline with MoveNet's detector (its network replaced by one returning these people): a pair 2.5 m
    # ahead of the robot, side by side facing each other (+y and -y). The group model's members carry those facings
    from ssbl_pb.perception.camera import sim_camera
    from ssbl_pb.perception.detection.ranging import PinholeGeometry

    geom = PinholeGeometry(sim_camera(RobotParams(), 320, 240))
    pair = [(np.array([2.5, -0.45]), math.pi / 2), (np.array([2.5, 0.45]), -math.pi / 2)]
    rows = np.stack([person_row(geom, xy, yaw) for xy, yaw in pair])
    members = movenet_deploy(rows)
    assert len(members) == 2
    for m in members:
        truth = pair[int(m.pos[1] > 0)]
        assert np.hypot(*(m.pos - truth[0])) < 0.3
        assert m.facing is not None and abs(math.remainder(m.facing - truth[1], 2 * math.pi)) < math.radians(15)


def test_deploy_keeps_a_movenet_person_the_image_side_cuts_only_where_a_laser_places_them():
    # deploy's pipeline with MoveNet's detector (its network replaced): one person 2 m straight ahead, one 1.8 m
    # away at the image's side (their box cut). Without laser returns the cut one is dropped; with returns on their
    # near side they are placed there, their facing unknown (the keypoints of half a body)
    from ssbl_pb.deploy.perceive import BODY_MARGIN, whole_people
    from ssbl_pb.perception.camera import sim_camera
    from ssbl_pb.perception.detection.ranging import PinholeGeometry

    cam = sim_camera(RobotParams(), 320, 240)
    geom = PinholeGeometry(cam)
    side = 1.8 * np.array([math.cos(math.radians(26)), math.sin(math.radians(26))])
    people_xy = [np.array([2.0, 0.0]), side]
    rows = np.stack([person_row(geom, xy, math.atan2(-xy[1], -xy[0])) for xy in people_xy])  # facing the robot
    assert whole_people(rows[:, :4], 320, BODY_MARGIN).tolist() == [True, False]

    u = side / np.hypot(*side)
    near = side - 0.1 * u  # a real Pepper's lasers hit the shins 0.1 m in front of the centre (LEG_DEPTH_M)
    returns = near + np.outer([-0.06, 0.0, 0.06], [-u[1], u[0]])
    found = {lasers: sorted(movenet_deploy(rows, returns=returns if lasers else None), key=lambda m: m.pos[1])
             for lasers in (False, True)}
    assert len(found[False]) == 1 and np.hypot(*(found[False][0].pos - people_xy[0])) < 0.3
    assert len(found[True]) == 2
    cut = found[True][1]
    assert np.hypot(*(cut.pos - side)) < 0.05 and cut.facing is None
    assert found[True][0].facing is not None


def test_facing_errors_by_hand():
    from ssbl_pb.bench.pets_facing import facing_errors, summarise

    # one GT person walking +x at 1 m/s on frames 0-3, one standing; a track on the walker facing 20 deg, then
    # 100 deg, one 3 m away (not matched), none on frame 3
    motion = np.array([[f, 1, f / 7, 0.0, 1.0, 0.0] for f in range(4)] + [[f, 2, 5.0, 5.0, 0.0, 0.0] for f in range(4)])
    tracks = np.array([[0, 7, 0.1, 0.0, 20.0], [1, 7, 1 / 7, 0.2, -100.0], [2, 7, 2 / 7, 3.0, 0.0],
                       [2, 8, 5.0, 5.0, 90.0]])
    r = facing_errors(tracks, motion, 0, 4)
    assert r["walker_frames"] == 4 and r["matched"] == 2 and r["with_facing"] == 2
    np.testing.assert_allclose(r["errors_deg"], [20.0, 100.0])
    assert r["median_deg"] == 60.0 and r["within_45"] == 0.5 and not r["meets_target"]
    assert summarise(np.full(10, 29.0))["meets_target"]


def test_the_reversed_copy_is_the_frames_last_first(tmp_path):
    from ssbl_pb.bench.pets_facing import write_reversed
    from ssbl_pb.perception.tracking.pipeline import read_frames

    src = tmp_path / "in.avi"
    w = cv2.VideoWriter(str(src), cv2.VideoWriter_fourcc(*"FFV1"), 7, (64, 48))
    frames = [np.full((48, 64, 3), 30 * k, np.uint8) for k in range(6)]
    for f in frames:
        w.write(f)
    w.release()
    assert write_reversed(src, 1, 5, tmp_path / "rev.avi") == 4
    back = [f for _, f in read_frames(tmp_path / "rev.avi")]
    assert [int(f[0, 0, 0]) for f in back] == [120, 90, 60, 30]


def test_bench_tool_names_missing_data(tmp_path, capsys):
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_pets_facing", ROOT / "tools" / "bench_pets_facing.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(["--data", str(tmp_path / "none"), "--out", str(tmp_path / "out")]) == 2
    assert "vtest.avi: not found" in capsys.readouterr().err and not list(tmp_path.iterdir())
