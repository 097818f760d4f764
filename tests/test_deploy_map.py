"""Deploy on a map: the room YAML of tools/import_map.py, the start pose checks, odometry -> room -> map poses
held to the simulator's truth, the walls the policy sees, and paths.png drawn on the occupancy map."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ssbl_pb.agents.policies import make_policy
from ssbl_pb.deploy.frames import Frames, load_room
from ssbl_pb.deploy.log import RunLog, read_log
from ssbl_pb.deploy.loop import DeployLoop, DeployParams, Setup
from ssbl_pb.deploy.perceive import Perception
from ssbl_pb.deploy.plot import draw
from ssbl_pb.errors import UserError
from ssbl_pb.params import RobotParams, SocialParams
from ssbl_pb.virtual.pepper import write_room_map
from ssbl_pb.virtual.robot import SimClock, SimRobot


@pytest.fixture
def robot():
    r = SimRobot("default", seed=35)  # the group is in view from the start (1 deg off the heading)
    yield r
    r.close()


def test_start_pose_must_be_on_free_space_of_the_map(robot, tmp_path):
    room_yaml, start = write_room_map(tmp_path, robot)
    room = load_room(room_yaml)
    assert room.room_size == (10.0, 10.0) and room.map_to_room[:2] == pytest.approx([2.0, 1.0], abs=0.05)
    Frames(room, start).check_start()  # the robot's true start is fine
    with pytest.raises(UserError, match="outside the map"):
        Frames(room, np.array([40.0, 0.0, 0.0])).check_start()
    with pytest.raises(UserError, match="an occupied cell"):
        Frames(room, np.array([2.0 + 5.05, 1.0, 0.0])).check_start()  # on the +x wall
    with pytest.raises(UserError, match="needs --start-pose"):
        Frames(room, None).check_start()


def test_run_on_the_map_logs_true_poses_and_draws_them(robot, tmp_path):
    room_yaml, start = write_room_map(tmp_path / "map", robot)
    frames = Frames(load_room(room_yaml), start)
    clock = SimClock(robot)
    social = SocialParams()
    perception = Perception(robot, clock.now, "colour", RobotParams(), social=social, threaded=False)
    log = RunLog(tmp_path)
    (tmp_path / "run.json").write_text(f'{{"map": "{room_yaml}"}}')
    loop = DeployLoop(Setup(robot, make_policy("sffm", RobotParams(), social, seed=0), perception, frames),
                      DeployParams(status_s=0, duration_s=6.0), log, now=clock.now, sleep=clock.sleep)
    poses = []
    tick = loop.tick

    def record(*args):
        poses.append(robot.world.robot_pose.copy())  # the truth when the tick reads odometry
        return tick(*args)

    loop.tick = record
    assert loop.run()[0] == "duration"
    log.close()
    rows = read_log(tmp_path)
    offset = frames.room.map_to_room
    for row, truth in zip(rows, poses, strict=True):
        assert row["room_pose"] == pytest.approx(truth, abs=1e-6)
        assert row["map_pose"][:2] == pytest.approx(truth[:2] + offset[:2], abs=1e-6)
    x, y = poses[-1][:2]
    assert frames.walls(poses[-1]) == pytest.approx([5 - x, x + 5, 5 - y, y + 5])
    png = draw(tmp_path)
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] >= 800
    # the whole room is drawn: its 0.1 m walls (black) all around, ~40 m of them at ~70 px/m
    assert (img == 0).all(axis=2).sum() > 10000
    assert any(row["humans"] for row in rows)  # and people were tracked (their paths are drawn too)


def test_scan_from_the_map_is_the_simulators(tmp_path):
    """Deploy casts the scan from the room YAML at the localised pose exactly as the simulator does in that room."""
    from ssbl_pb.core import observation as ob
    from ssbl_pb.env.gymenv.approach import make_env

    r = SimRobot("default", seed=35)
    try:
        room_yaml, _ = write_room_map(tmp_path, r)
    finally:
        r.close()
    with open(room_yaml, "a") as fh:
        fh.write("obstacles:\n  boxes:\n  - [1.5, 0.5, 1.4, 0.7, 0]\n  - [-2.0, -1.0, 0.8, 0.8, 45]\n")
    frames = Frames(load_room(room_yaml), np.zeros(3))
    env = make_env(room_yaml=room_yaml, scenario="default")
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        sim = env.unwrapped.sim
        frame = ob.approach_yaw(sim.pose[0], sim.centre[0])
        assert np.allclose(frames.scan(sim.pose[0], frame), obs[ob.BASE_SIZE:], atol=1e-6)
    assert (frames.scan(np.array([0.8, 0.5, 0.0]), 0.0) < 1).sum() >= 3  # the desk fills several rays
    assert np.all(Frames().scan(np.zeros(3), 0.0) == 1.0)  # no map: nothing known
