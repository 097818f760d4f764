"""SFFM eqs. 8-10 against hand computations, including degenerate cases."""

import math

import numpy as np
import pytest

from ssbl_pb.core import forces


def _mask(k, mask):
    return np.ones((k, k), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)


def repulsion(P, d_p, mask=None):
    """``forces.repulsion_on`` for every agent (one zone radius or a (k, k) array of them)."""
    P = np.asarray(P, dtype=float)
    zones = np.broadcast_to(np.asarray(d_p, dtype=float), (len(P), len(P))).astype(float)
    return np.array([forces.repulsion_on(a, P, zones, _mask(len(P), mask)) for a in range(len(P))])


def equality(P, d_s, mask=None):
    P = np.asarray(P, dtype=float)
    out = np.array([forces.equality_on(a, P, d_s, _mask(len(P), mask)) for a in range(len(P))])
    return out[:, :2], out[:, 2:]


def cohesion(P, o, s, d_s, d_pub, mask=None):
    P = np.asarray(P, dtype=float)
    out = np.array([forces.cohesion_on(a, P, float(o[0]), float(o[1]), s, d_s, d_pub, _mask(len(P), mask))
                    for a in range(len(P))])
    return out[:, :2], out[:, 2:]


def test_normalize_is_safe_at_zero():
    unit, n = forces.normalize(np.array([[3.0, 4.0], [0.0, 0.0]]))
    assert unit[0] == pytest.approx([0.6, 0.8])
    assert unit[1] == pytest.approx([0.0, 0.0])
    assert n == pytest.approx([5.0, 0.0])


def test_soft_normalize_linear_then_unit():
    v = forces.soft_normalize(np.array([[0.1, 0.0], [2.0, 0.0]]), 0.5)
    assert v[0] == pytest.approx([0.2, 0.0])
    assert v[1] == pytest.approx([1.0, 0.0])


def test_repulsion_hand_computed():
    # agent 0 at origin; agents 1 (0.5, 0) and 2 (0, 1.0) inside d_p = 1.2; agent 3 far away.
    P = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 1.0], [5.0, 5.0]])
    F = repulsion(P, 1.2)
    # p_r = (0.5, 1.0); d_min = 0.5; |F| = (1.2 - 0.5)^2 = 0.49, direction -p_r/|p_r|
    expected = -0.49 * np.array([0.5, 1.0]) / math.hypot(0.5, 1.0)
    assert F[0] == pytest.approx(expected)
    assert F[3] == pytest.approx([0.0, 0.0])  # nobody in its personal zone


def test_repulsion_coincident_agents_are_finite_and_zero():
    F = repulsion(np.array([[1.0, 1.0], [1.0, 1.0]]), 1.2)
    assert np.all(np.isfinite(F)) and np.allclose(F, 0.0)


def test_equality_hand_computed():
    P = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 4.0]])
    F, d = equality(P, 5.0)
    # agent 0: all inside 5 m -> c = (2/3, 4/3); distances to c: 1.4907, 1.9437, 2.7487; m = 2.0610
    c = np.array([2 / 3, 4 / 3])
    dists = np.hypot(*(P - c).T)
    m = dists.mean()
    assert F[0] == pytest.approx((1 - m / dists[0]) * (c - P[0]))
    assert d[0] == pytest.approx([2.0, 4.0])
    # agent 1 sees agent 2 at 4.47 m (< 5) and agent 0 -> same centroid
    assert F[1] == pytest.approx((1 - m / dists[1]) * (c - P[1]))


def test_equality_alone_is_zero():
    F, d = equality(np.array([[0.0, 0.0], [10.0, 0.0]]), 5.0)
    assert np.allclose(F, 0.0) and np.allclose(d, 0.0)


def test_equality_pair_is_in_equilibrium():
    F, _ = equality(np.array([[-1.0, 0.0], [1.0, 0.0]]), 5.0)
    assert np.allclose(F, 0.0)


def test_cohesion_hand_computed():
    P = np.array([[3.0, 0.0], [0.0, 1.0], [20.0, 0.0]])
    o = np.array([0.0, 0.0])
    F, d = cohesion(P, o, 1.0, 5.0, 8.0)
    # agent 0: N_a = 1 (agent 1 at 3.16 m), N_s = 1 -> alpha = 1/2; F = 0.5 (1 - 1/3) (-3, 0) = (-1, 0)
    assert F[0] == pytest.approx([-1.0, 0.0])
    assert d[0] == pytest.approx([-3.0, 1.0])
    # agent 1 sits on the o-space circle: no force
    assert F[1] == pytest.approx([0.0, 0.0])
    # agent 2: nobody within the public zone -> alpha = 0
    assert F[2] == pytest.approx([0.0, 0.0])


def test_cohesion_agent_at_centre_is_finite():
    F, _ = cohesion(np.array([[0.0, 0.0], [1.0, 0.0]]), np.zeros(2), 1.0, 5.0, 8.0)
    assert np.all(np.isfinite(F)) and F[0] == pytest.approx([0.0, 0.0])


def test_single_member_feels_nothing():
    P = np.array([[2.0, 0.0]])
    assert np.allclose(repulsion(P, 1.2), 0.0)
    assert np.allclose(equality(P, 5.0)[0], 0.0)
    assert np.allclose(cohesion(P, np.zeros(2), 1.0, 5.0, 8.0)[0], 0.0)


def test_mask_excludes_neighbours():
    P = np.array([[0.0, 0.0], [0.5, 0.0]])
    mask = np.array([[True, False], [True, True]])
    F = repulsion(P, 1.2, mask)
    assert np.allclose(F[0], 0.0) and not np.allclose(F[1], 0.0)


def test_repulsion_with_a_zone_per_pair_takes_the_deepest_intrusion():
    # agent 0 keeps 0.8 m from agent 1 (at 0.5 m: 0.3 deep) and 1.2 m from agent 2 (at 1.0 m: 0.2 deep)
    P = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 1.0]])
    zones = np.array([[0.0, 0.8, 1.2], [0.8, 0.0, 1.2], [1.2, 1.2, 0.0]])
    F = repulsion(P, zones)
    assert F[0] == pytest.approx(-(0.3 ** 2) * np.array([0.5, 1.0]) / math.hypot(0.5, 1.0))
    # the per-agent function the members' step calls gives the same
    mask = np.ones((3, 3), dtype=bool)
    assert forces.repulsion_on(0, P, zones, mask) == pytest.approx(tuple(F[0]))
