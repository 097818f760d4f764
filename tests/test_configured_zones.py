"""The configured task's intimate zone in spawning and in the SFFM baseline, the SFFM's
robot radius from the given robot, and ``WorldParams``' group fields refused however they are given."""

import math

import numpy as np
import pytest
import yaml

from ssbl_pb.agents.policies import SFFMPolicy, make_policy
from ssbl_pb.core.observation import OBS_SIZE, POS_SCALE
from ssbl_pb.core.task import TaskParams
from ssbl_pb.env.engine.batched import BatchedApproach
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.env.rooms import spawn
from ssbl_pb.params import ConfigError, RobotParams, SocialParams, WorldParams


# -- 1. spawning keeps the configured task's intimate zone -------------------------------------------------------
def test_furnished_spawn_keeps_out_of_the_configured_intimate_zone(monkeypatch):
    made: list[spawn.Approach] = []

    class Recorded(spawn.Approach):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(spawn, "Approach", Recorded)
    batch = BatchedApproach(1, scenario="default@furnished", task={"intimate_zone": 0.8})
    batch.seed(0, 5)
    batch.reset(0)
    assert made
    reach = 0.5 * math.hypot(0.48, 0.43)  # the default footprint's corner
    for a in made:  # members' ring + body 0.28 m + corner + the task's 0.8 m (not the default 0.45 m)
        ring = float(np.hypot(a.offsets[:, 0], a.offsets[:, 1]).max())
        assert a.keep_out == pytest.approx(ring + 0.28 + reach + 0.8, abs=1e-12)
    # the start that fitted is outside that keep-out disc
    start, centre = batch.pose[0, :2], batch.groups_state.centre[0]
    assert np.hypot(*(start - centre)) > made[-1].keep_out


def test_fitting_sizes_passes_its_task_on(monkeypatch):
    zones: list[float] = []
    real = spawn.spawn_layout

    def spy(*args, **kwargs):
        zones.append(kwargs["task"].intimate_zone)
        return real(*args, **kwargs)

    monkeypatch.setattr(spawn, "spawn_layout", spy)
    from ssbl_pb.env.rooms.rooms import Room

    spawn.fitting_sizes(Room((10.0, 10.0)), tries=1, task=TaskParams(intimate_zone=0.7))
    assert zones and set(zones) == {0.7}


# -- 2. the SFFM baseline reads the robot and the task it is given ----------------------------------------------
def _members_obs(members: list[tuple[float, float]], slot: tuple[float, float], centre: tuple[float, float],
                 radius: float) -> np.ndarray:
    """A Vector observation (approach frame, robot at the origin, at rest) with ``members`` in metres."""
    obs = np.zeros(OBS_SIZE, dtype=np.float32)
    obs[0:2], obs[2:4], obs[4] = np.array(slot) / POS_SCALE, np.array(centre) / POS_SCALE, radius / POS_SCALE
    for k, (x, y) in enumerate(members):
        obs[14 + 5 * k: 14 + 5 * k + 5] = (x / POS_SCALE, y / POS_SCALE, 0.0, 0.0, 1.0)
    return obs


def test_sffm_personal_zone_uses_the_given_robot_and_intimate_zone():
    members, slot = np.array([[1.0, 0.5], [1.0, -0.5]]), np.array([1.0, 0.0])
    # the place is 0.5 m from both members, inside the bodies: the zone is intimate + margin 0.3 + both bodies
    default = SFFMPolicy().personal_zone(members, slot)
    assert default == pytest.approx(0.45 + 0.3 + 0.28 + 0.25 * (0.48 + 0.43), abs=1e-12)
    big = SFFMPolicy(robot=RobotParams(length=0.8, width=0.8), task=TaskParams(intimate_zone=0.6))
    assert big.personal_zone(members, slot) == pytest.approx(0.6 + 0.3 + 0.28 + 0.4, abs=1e-12)
    via_name = make_policy("sffm", RobotParams(length=0.8, width=0.8), task=TaskParams(intimate_zone=0.6))
    assert via_name.personal_zone(members, slot) == big.personal_zone(members, slot)


def test_sffm_bigger_robot_is_repelled_where_the_default_is_not():
    # members at (1, +-1.5): 1.803 m from the robot; the place (behind it) is 2.5 m from them, so the zone is the
    # personal 1.2 m plus both bodies: 1.7075 m by default (outside it), 1.2 + 0.28 + 0.4 = 1.88 m for a 0.8 m
    # square robot (inside it). Cohesion and equality do not depend on the robot, so the difference is the
    # repulsion alone: weight 2, full strength, away from the members' sum, i.e. (-2, 0)
    obs = _members_obs([(1.0, 1.5), (1.0, -1.5)], slot=(-1.0, 0.0), centre=(1.0, 0.0), radius=1.0)
    assert math.hypot(1.0, 1.5) > 1.2 + 0.28 + RobotParams().radius
    small = SFFMPolicy().force(obs)
    big = SFFMPolicy(robot=RobotParams(length=0.8, width=0.8)).force(obs)
    np.testing.assert_allclose(big - small, [-2.0, 0.0], atol=1e-9)


def test_sffm_default_matches_the_hard_coded_numbers():
    # the constants it replaced (robot radius 0.2275 m, intimate zone 0.45 m): the same zone to the last bit
    members, slot = np.array([[1.0, 0.5], [2.0, 0.7]]), np.array([1.3, 0.1])
    place = float(np.hypot(*(members - slot).T).min()) - (0.28 + 0.2275)
    old = min(1.2, max(place, 0.45) + 0.3) + (0.28 + 0.2275)
    assert SFFMPolicy(SocialParams()).personal_zone(members, slot) == old


# -- 3. WorldParams' group fields are refused as an instance too ------------------------------------------------
@pytest.mark.parametrize(("world", "field"), [
    (WorldParams(n_humans=4), "world.n_humans = 4"),
    (WorldParams(formation="circular"), "world.formation = 'circular'"),
    ({"n_humans": 4}, "world.n_humans = 4"),
])
def test_world_group_fields_are_refused_by_name(world, field):
    with pytest.raises(ConfigError, match=f"{field}: the scenario sets the group"):
        ApproachGroupEnv(world=world)


def test_default_world_instance_is_accepted_with_a_room_yaml(tmp_path):
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump({"world": {"room_size": [8.0, 8.0]}}))
    env = ApproachGroupEnv(world=WorldParams(dt=0.2), room_yaml=str(path))
    assert env.world_params.dt == 0.2 and env.world_params.n_humans == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"world": {"room_size": [8.0, 8.0], "formation": "circular"}}))
    with pytest.raises(ConfigError, match="bad.yaml: world.formation = 'circular'"):
        ApproachGroupEnv(room_yaml=str(bad))
