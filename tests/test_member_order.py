"""The observation's member order (``core.observation.MEMBER_ORDERS``): nearest first or by bearing, the same in
the env, in deploy's observation and in a trained policy's recorded config."""

from __future__ import annotations

import numpy as np
import pytest

from ssbl_pb.core import observation as ob
from ssbl_pb.env.gymenv.approach import ApproachGroupEnv
from ssbl_pb.errors import UserError


def _blocks(obs: np.ndarray) -> np.ndarray:
    return np.asarray(obs[ob.MEMBERS:ob.HEADING]).reshape(ob.MAX_MEMBERS, ob.MEMBER_FIELDS)


def _obs(robot_y: float, members: np.ndarray, order: str) -> np.ndarray:
    """The robot at (0, robot_y) facing +x, the centre at (2, 0)."""
    return ob.vector_observation(np.array([0.0, robot_y, 0.0]), np.zeros(3), members, np.zeros_like(members),
                                 np.array([2.0, 0.0]), 0.8, np.array([1.2, 0.0]), np.full(4, 5.0), 0.35, 1.0,
                                 frame_yaw=0.0, member_order=order)


def test_in_front_of_a_gap_the_nearest_block_swaps_sides_and_the_bearing_order_does_not():
    """Two members 1.2 m apart, the robot 2 cm either side of the line between them: nearest first, block 0 is
    the member on the robot's own side (left, then right); by bearing it is the left member both times."""
    members = np.array([[1.5, -0.6], [1.5, 0.6], [2.6, 0.0]])
    left_of_gap, right_of_gap = _obs(0.02, members, "nearest"), _obs(-0.02, members, "nearest")
    assert _blocks(left_of_gap)[0, ob.MEMBER_Y] > 0 > _blocks(right_of_gap)[0, ob.MEMBER_Y]
    for y in (0.02, -0.02):
        b = _blocks(_obs(y, members, "bearing"))
        # block y (m, robot frame): 0.6 - y, then the far member straight ahead (-y), then -0.6 - y
        assert b[:3, ob.MEMBER_Y] * ob.POS_SCALE == pytest.approx([0.6 - y, -y, -0.6 - y], abs=1e-6)
        assert b[3:, ob.MEMBER_PRESENT].tolist() == [0.0, 0.0]


def test_bearing_order_keeps_the_five_nearest():
    """Six people: the farthest is left out (as nearest first), the rest ordered by bearing."""
    members = np.array([[2.0, 3.0], [2.0, 1.0], [2.0, -1.0], [2.0, -0.2], [1.0, 0.3], [9.0, 0.0]])
    b = _blocks(_obs(0.0, members, "bearing"))
    xy = b[:, :2] * ob.POS_SCALE
    bearings = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    assert np.all(np.diff(bearings) < 0)  # leftmost first
    assert xy[np.lexsort(xy.T[::-1])] == pytest.approx(members[:5][np.lexsort(members[:5].T[::-1])], abs=1e-6)


def test_env_orders_members_by_bearing_when_asked():
    near = ApproachGroupEnv(scenario="circular-4")
    bear = ApproachGroupEnv(scenario="circular-4", member_order="bearing")
    a, _ = near.reset(seed=4)
    b, _ = bear.reset(seed=4)
    ma, mb = ob.decode_members(a)[0], ob.decode_members(b)[0]
    assert np.all(np.diff(np.hypot(*ma.T)) >= 0)
    assert np.all(np.diff(np.arctan2(mb[:, 1], mb[:, 0])) < 0)
    assert ma[np.lexsort(ma.T[::-1])] == pytest.approx(mb[np.lexsort(mb.T[::-1])], abs=1e-5)
    outside = np.r_[0:ob.MEMBERS, ob.HEADING:ob.OBS_SIZE]
    assert a[outside] == pytest.approx(b[outside])


def test_unknown_member_order_is_refused():
    with pytest.raises(UserError, match=r"member_order 'random': expected one of \['nearest', 'bearing'\]"):
        ApproachGroupEnv(member_order="random")


def test_a_trained_policy_brings_its_member_order(tmp_path):
    """Deploy and evaluation read the order from the model's config (``trained.OBSERVATION_KEYS``)."""
    import yaml

    from ssbl_pb.agents.trained import ModelError, PolicyView, policy_env_kwargs, policy_view
    from ssbl_pb.training.config import load_config

    assert policy_view("vector") == PolicyView(True, True, "nearest")  # the shipped policy's
    assert policy_view("sffm") == PolicyView()
    run = tmp_path / "run"
    run.mkdir()
    (run / "model.zip").write_bytes(b"zip")
    (run / "vecnormalize.pkl").write_bytes(b"norm")
    (run / "config.yaml").write_text(yaml.safe_dump({"obs_mode": "vector", "env": {"member_order": "bearing"}}))
    assert policy_env_kwargs(str(run)) == {"member_order": "bearing"}
    assert policy_view(str(run)) == PolicyView(member_order="bearing")
    assert load_config(None, {"env": {"member_order": "bearing"}}).env["member_order"] == "bearing"
    (run / "config.yaml").write_text(yaml.safe_dump({"obs_mode": "vector", "env": {"member_order": "random"}}))
    with pytest.raises(ModelError, match=r"run/config.yaml: env.member_order 'random': expected one of \['nearest'"):
        policy_view(str(run))
