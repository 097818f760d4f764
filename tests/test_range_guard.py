"""What the base's lasers see of a person, and the range guard the simulator keeps for the members deploy's
perception missed (deploy's ``guards.guard_ranges`` on the true bodies)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ssbl_pb.core.range_sensors import RETURN_MARGIN, brake_for_bodies, lasers_see_body
from ssbl_pb.core.shield import ShieldParams
from ssbl_pb.core.task import TaskParams
from ssbl_pb.env.engine.batched import BatchedApproach
from ssbl_pb.params import RobotParams, SocialParams

SHIELD = ShieldParams.from_env(RobotParams(), SocialParams(), TaskParams())
CLEAR = TaskParams().intimate_zone + RETURN_MARGIN  # 0.5 m


def _at(bearing_deg: float, distance: float) -> np.ndarray:
    b = math.radians(bearing_deg)
    return np.array([[distance * math.cos(b), distance * math.sin(b)]])


def test_the_lasers_see_a_body_ahead_and_aside_but_not_in_the_blind_sector_between():
    # front laser +-30 deg; the side ones at +-100.7 deg, +-30 deg: blind from about 30 to 70 deg either side. At
    # 1.5 m a body's 0.28 m radius spans +-10.7 deg of bearing
    assert lasers_see_body(_at(0, 1.5), SHIELD.human_radius).all()
    assert lasers_see_body(_at(-95, 1.5), SHIELD.human_radius).all()
    assert not lasers_see_body(_at(50, 1.5), SHIELD.human_radius).any()  # 39-61 deg: all of it blind
    assert lasers_see_body(_at(38, 1.5), SHIELD.human_radius).all()  # its right side at 27 deg: the front's
    assert not lasers_see_body(_at(38, 1.5), 0.0).any()  # a point there is not
    assert not lasers_see_body(_at(0, 3.5), SHIELD.human_radius).any()  # beyond the lasers' 3 m


def test_a_body_the_lasers_see_is_braked_for_by_the_shields_rule_and_one_they_do_not_see_is_not():
    reach = math.hypot(SHIELD.half_length, SHIELD.half_width)
    gap = 1.2 - reach - SHIELD.human_radius  # footprint circle to the body's circle, straight ahead
    allow = math.sqrt(2 * SHIELD.brake_accel * (gap - CLEAR))
    v = brake_for_bodies(np.array([0.35, 0.1]), _at(0, 1.2), CLEAR, SHIELD)
    assert v == pytest.approx([allow, 0.1])  # the closing speed cut, the motion across kept
    assert brake_for_bodies(np.array([0.35, 0.1]), _at(50, 1.2), CLEAR, SHIELD) == pytest.approx([0.35, 0.1])
    assert brake_for_bodies(np.array([-0.2, 0.0]), _at(0, 1.2), CLEAR, SHIELD) == pytest.approx([-0.2, 0.0])


def test_with_the_observation_model_the_engine_brakes_for_a_member_ahead_that_perception_does_not_know():
    b = BatchedApproach(1, "default", perception=True)
    b.seed(0, 3)
    b.reset(0)
    g = b.groups_state
    pose = np.array([0.0, 0.0, 0.0])
    b.pose[0] = pose
    g.pos[0, 0] = [1.2, 0.0]  # a member 1.2 m straight ahead
    g.pos[0, 1:int(g.count[0])] = [[-3.0, 3.0]] * (int(g.count[0]) - 1)  # the others behind, far off
    aim = np.array([[3.0, 0.0]])  # the centre the robot perceives, straight ahead: the action frame is the body's
    out = b._range_guard(np.array([[1.0, 0.0]]), aim)
    reach = math.hypot(SHIELD.half_length, SHIELD.half_width)
    allow = math.sqrt(2 * SHIELD.brake_accel * (1.2 - reach - SHIELD.human_radius - CLEAR))
    assert out[0] == pytest.approx([allow / b.robot_params.max_speed, 0.0])
    aim = np.array([[0.0, 3.0]])  # facing the centre to the left: the action (toward it, left of it) turns back
    out = b._range_guard(np.array([[0.0, -1.0]]), aim)  # = straight ahead in the body frame
    assert out[0] == pytest.approx([0.0, -allow / b.robot_params.max_speed])
    g.pos[0, 0] = _at(50, 1.2)[0]  # in the blind sector: nothing to brake for
    assert b._range_guard(np.array([[0.3, 0.2]]), aim) == pytest.approx(np.array([[0.3, 0.2]]))


def test_the_engine_guards_every_step_with_the_model_on_and_never_with_it_off(monkeypatch):
    calls = []
    original = BatchedApproach._range_guard

    def spy(self, actions, aim):
        calls.append(len(actions))
        return original(self, actions, aim)

    monkeypatch.setattr(BatchedApproach, "_range_guard", spy)
    for perception, expected in ((True, [1, 1]), (False, [])):
        calls.clear()
        b = BatchedApproach(1, "default", perception=perception)
        b.seed(0, 3)
        b.reset(0)
        for _ in range(2):
            b.step(np.zeros((1, b.n_act)))
        assert calls == expected, perception


def test_a_member_the_lasers_saw_and_nobody_tracks_is_braked_for_in_the_blind_sector_they_stepped_into():
    """Deploy's ``RangeMemory`` in the engine: a member perception never tracked, seen by the front laser at 25 deg,
    then standing at 50 deg (the blind sector), is braked for half a second later; a new episode forgets them."""
    b = BatchedApproach(1, "default", perception=True)
    b.seed(0, 3)
    b.reset(0)
    g, n = b.groups_state, int(b.groups_state.count[0])
    b.pose[0] = [0.0, 0.0, 0.0]
    b.perceived.count[0] = 0  # perception tracks nobody: no track explains what the lasers see
    g.pos[0, 1:n] = [[-3.0, 3.0]] * (n - 1)
    aim = np.array([[3.0, 0.0]])  # straight ahead: the action frame is the body's
    g.pos[0, 0] = _at(25, 1.6)[0]
    b.steps[0] = 0
    b._range_guard(np.zeros((1, 2)), aim)  # the front laser sees them
    g.pos[0, 0] = _at(50, 1.2)[0]
    b.steps[0] = 5  # 0.5 s on: they may have walked 0.5 m unseen
    toward = np.array([[math.cos(math.radians(50)), math.sin(math.radians(50))]])
    out = b._range_guard(toward, aim)
    assert out[0] @ toward[0] < 0.5  # the closing speed cut by half at least
    b._range_memory[0].clear()
    assert b._range_guard(toward, aim) == pytest.approx(toward)  # nothing remembered: nothing in view to brake for
