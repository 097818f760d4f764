"""Groups keep their F-formation alone and open a place for a newcomer at the o-space edge."""

import math

import numpy as np
import pytest

from ssbl_pb.core.humans import Group, formation_angles, widest_gap
from ssbl_pb.core.layouts import paper_layout
from ssbl_pb.params import FORMATIONS, SocialParams

SOCIAL = SocialParams()
FAR = np.array([30.0, 30.0])


def paper_group(formation, n, rotation=0.0, centre=(0.0, 0.0)):
    return Group(SOCIAL, np.array(centre), paper_layout(formation, n, SOCIAL, rotation))


@pytest.mark.parametrize("formation", FORMATIONS)
@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_group_left_alone_stays_put(formation, n):
    if formation == "circular" and n == 2:
        pytest.skip("a 2-member circle is a vis-a-vis")
    g = paper_group(formation, n, 0.4, (1.0, -2.0))
    start, yaw0 = g.pos.copy(), g.yaw.copy()
    for _ in range(300):
        g.step(FAR, 0.1)
    assert np.abs(g.pos - start).max() < 1e-6
    assert np.abs(np.angle(np.exp(1j * (g.yaw - yaw0)))).max() < 1e-6
    # members face the o-space centre
    to_centre = np.arctan2(*(g.centre0 - g.pos).T[::-1])
    assert np.abs(np.angle(np.exp(1j * (g.yaw - to_centre)))).max() < 1e-6


def test_members_keep_comfortable_spacing():
    for n in range(2, 6):
        g = paper_group("circular" if n > 2 else "vis_a_vis", n)
        d = np.hypot(*(g.pos[:, None] - g.pos[None]).transpose(2, 0, 1))
        d[np.diag_indices(n)] = np.inf
        assert d.min() >= SOCIAL.min_member_gap - 1e-9


def test_newcomer_at_ospace_edge_opens_a_place():
    g = paper_group("circular", 3)
    mid = 0.5 * (g.member_angles()[0] + g.member_angles()[1])
    robot = (g.base_radius + 0.1) * np.array([math.cos(mid), math.sin(mid)])
    gap0 = abs(g.member_angles()[1] - g.member_angles()[0])
    dmin0 = np.hypot(*(g.pos - robot).T).min()
    for _ in range(100):
        g.step(robot, 0.1)
    ang = np.angle(np.exp(1j * (g.member_angles() - math.atan2(*(robot - g.centre)[::-1]))))
    gap = np.sort(np.abs(ang))[:2].sum()
    assert gap > gap0 + math.radians(30)  # the two neighbours step apart
    assert np.hypot(*(g.pos - robot).T).min() > dmin0 + 0.1
    assert np.abs(g.vel).max() < 0.05  # and settle


def test_pair_turns_toward_newcomer():
    g = paper_group("vis_a_vis", 2)
    robot = np.array([0.0, -1.3])
    for _ in range(50):
        g.step(robot, 0.1)
    # both members turn from facing each other toward the new centre, on the robot's side
    assert np.all(np.sin(g.yaw) < -0.05)
    slot = g.free_slot(robot)
    assert np.hypot(*(slot - robot)) < 0.3


def test_widest_gap_tie_break_toward_robot():
    mid, gap = widest_gap(np.array([0.0, math.pi]), -math.pi / 2, True, 10.0)
    assert gap == pytest.approx(math.pi)
    assert math.sin(mid) == pytest.approx(-1.0)
    mid, _ = widest_gap(np.array([0.0, math.pi]), math.pi / 2, True, 10.0)  # the robot on the other side
    assert math.sin(mid) == pytest.approx(1.0)


def test_bad_group_size_rejected():
    with pytest.raises(ValueError, match="group size 1"):
        formation_angles("circular", 1, SOCIAL)
    with pytest.raises(ValueError, match="formation 'blob'"):
        formation_angles("blob", 3, SOCIAL)
