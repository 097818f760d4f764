"""Reward terms (eqs. 11-15) against hand computations on a constructed two-step trajectory."""

import math

import numpy as np
import pytest

from ssbl_pb.core.reward import TERMS, RewardWeights, reward_terms, total_reward
from ssbl_pb.params import ConfigError

DT = 0.1


def two_steps():
    """Robot moves (0.03, 0) then (0.02, 0.01); one member is pushed (0, 0.01) in the second step."""
    return [
        dict(robot_force=np.array([1.0, 0.5]), robot_du=np.array([0.03, 0.0]),
             member_forces=np.array([[0.0, 0.0], [0.2, 0.0]]), member_du=np.zeros((2, 2)),
             member_repulsion=np.zeros((2, 2)), accel=np.array([0.5, 0.0]), prev_accel=np.zeros(2),
             potential_before=-2.0, potential_after=-1.97, success=False, violation=False),
        dict(robot_force=np.array([-1.0, 0.5]), robot_du=np.array([0.02, 0.01]),
             member_forces=np.array([[0.0, 0.3], [0.0, 0.0]]), member_du=np.array([[0.0, 0.01], [0.0, 0.0]]),
             member_repulsion=np.array([[0.0, -0.16], [0.0, 0.0]]), accel=np.array([0.5, 0.25]),
             prev_accel=np.array([0.5, 0.0]), potential_before=-1.97, potential_after=-0.2, success=True,
             violation=False),
    ]


def test_each_term_by_hand():
    s1, s2 = two_steps()
    t1 = reward_terms(**s1, dt=DT)
    t2 = reward_terms(**s2, dt=DT)
    # R1: F . du
    assert t1["r1_group_forming"] == pytest.approx(0.03)
    assert t2["r1_group_forming"] == pytest.approx(-0.02 + 0.005)
    # R2: dt when v . F > 0 (step 1: 0.3 > 0; step 2: v = (0.2, 0.1), v.F = -0.15 < 0)
    assert t1["r2_non_increasing"] == pytest.approx(DT)
    assert t2["r2_non_increasing"] == 0.0
    assert t1["r3_time"] == pytest.approx(-DT) and t2["r3_time"] == pytest.approx(-DT)
    # a violation with 12.3 s left pays that time too: ending early never beats the time-out
    crash = reward_terms(**{**s1, "violation": True}, dt=DT, remaining=12.3)
    assert crash["r3_time"] == pytest.approx(-DT - 12.3) and crash["violation"] == -1.0
    assert reward_terms(**s1, dt=DT, remaining=12.3)["r3_time"] == pytest.approx(-DT)
    assert t1["r4_success"] == 0.0 and t2["r4_success"] == 1.0
    # R5: -sum F_j . du_j; repulsion part -sum |F_rep| dt
    assert t1["r5_altruism"] == 0.0
    assert t2["r5_altruism"] == pytest.approx(-0.003)
    assert t2["r5_repulsion"] == pytest.approx(-0.016)
    # displacement: minus the members' path length this step (member 0 moved 0.01 m)
    assert t1["displacement"] == 0.0 and t2["displacement"] == pytest.approx(-0.01)
    pushed = reward_terms(**{**s2, "member_du": np.array([[0.03, 0.04], [0.0, -0.02]])}, dt=DT)
    assert pushed["displacement"] == pytest.approx(-0.07)
    # arrival: minus the speed at the step's end, on the success step only
    assert reward_terms(**s1, dt=DT, speed=0.08)["arrival"] == 0.0
    assert reward_terms(**s2, dt=DT, speed=0.08)["arrival"] == pytest.approx(-0.08)
    # effort: -|v|^2 dt, v = du / dt
    assert t1["effort"] == pytest.approx(-(0.3**2) * DT)
    assert t2["effort"] == pytest.approx(-(0.2**2 + 0.1**2) * DT)
    # smoothness: -|jerk| dt = -|a_t - a_{t-1}|
    assert t1["smoothness"] == pytest.approx(-0.5) and t2["smoothness"] == pytest.approx(-0.25)
    assert t2["slot_progress"] == pytest.approx(1.77)
    assert set(t1) == set(TERMS)


def test_total_is_eq15_with_our_terms():
    w = RewardWeights(w1=2.0, w2=3.0, w3=5.0, w4=7.0, w5=11.0, w_rep=13.0, w_e=0.5, w_a=0.25, w_effort=17.0,
                      w_smooth=19.0, w_slot=23.0, w_prox=31.0, violation_penalty=29.0, w_disp=37.0,
                      w_arrive=41.0)
    s1, s2 = two_steps()
    t = reward_terms(**s2, dt=DT, proximity=0.01, speed=0.05)
    ego = 2.0 * t["r1_group_forming"] + 3.0 * t["r2_non_increasing"] + 5.0 * t["r3_time"]
    expected = (0.5 * ego + 7.0 * 1.0 + 0.25 * (11.0 * t["r5_altruism"] + 13.0 * t["r5_repulsion"])
                + 17.0 * t["effort"] + 19.0 * t["smoothness"] + 23.0 * t["slot_progress"] - 31.0 * 0.01
                - 37.0 * 0.01 - 41.0 * 0.05)
    assert total_reward(t, w) == pytest.approx(expected)
    # the proximity cost enters with weight -w_prox, and only it differs when proximity is 0
    without = total_reward(reward_terms(**s2, dt=DT, speed=0.05), w)
    assert total_reward(t, w) - without == pytest.approx(-31.0 * 0.01)
    assert total_reward(reward_terms(**s1, dt=DT), w) != pytest.approx(without)  # the steps differ


def test_proximity_cost_charges_closing_in_near_the_intimate_zone():
    from ssbl_pb.core.reward import proximity_cost

    # intimate 0.45, band 0.3: member 0 closed 0.04 m to 0.55 (depth (0.75 - 0.55)/0.3 = 2/3); member 1 closed
    # 0.05 m but ends at 0.8, outside the band; member 2 moved away
    before, after = np.array([0.59, 0.85, 0.5]), np.array([0.55, 0.8, 0.52])
    assert proximity_cost(before, after, 0.45, 0.3) == pytest.approx(0.04 * 2 / 3)
    # standing still next to a member costs nothing; inside the zone the depth saturates at 1
    assert proximity_cost(after, after, 0.45, 0.3) == 0.0
    assert proximity_cost(np.array([0.45]), np.array([0.40]), 0.45, 0.3) == pytest.approx(0.05)


def test_reference_weights_match_original_per_step_values():
    w = RewardWeights.reference(dt=DT)
    # the original's ego per step: 0.012 v.F + 3.6 [v.F>0] - 2.0; with v.F = 1 m/s * 1 N and moving along F
    t = {k: 0.0 for k in TERMS}
    t.update(r1_group_forming=1.0 * DT, r2_non_increasing=DT, r3_time=-DT)
    assert total_reward(t, w) == pytest.approx(0.0035 * (0.012 + 3.6 - 2.0))


def test_violation_penalty_applies():
    s1, _ = two_steps()
    s1["violation"] = True
    w = RewardWeights()
    t = reward_terms(**s1, dt=DT)
    assert t["violation"] == -1.0
    assert total_reward(t, w) == pytest.approx(total_reward({**t, "violation": 0.0}, w) - w.violation_penalty)


def test_negative_weight_rejected():
    with pytest.raises(ConfigError, match="w3"):
        RewardWeights(w3=-1.0)


def test_slot_potential_rewards_braking_near_the_slot():
    from ssbl_pb.core.reward import slot_potential

    assert slot_potential(3.0, 0.35) == pytest.approx(-3.0)  # far: distance only
    assert slot_potential(0.5, 0.3) == pytest.approx(-(0.5 + 5.0 * 0.3 * 0.5))
    assert slot_potential(0.0, 0.0) == 0.0


def test_route_distance_goes_around_the_group():
    from ssbl_pb.core.reward import route_distance

    c, slot = np.zeros(2), np.array([1.0, 0.0])
    # straight in along the slot's ray
    assert route_distance(np.array([4.0, 0.0]), slot, c, 2.0) == pytest.approx(3.0)
    # from the far side: tangent sqrt(16 - 4), arc 2 (pi - acos(0.5)), then 1 m in from the rim
    far = route_distance(np.array([-4.0, 0.0]), slot, c, 2.0)
    assert far == pytest.approx(math.sqrt(12) + 2 * (math.pi - math.acos(0.5)) + 1.0)
    assert far > 5.0  # longer than the straight line through the group
    # inside the group, off the slot's ray: straight distance plus the arc to the ray
    assert route_distance(np.array([0.0, 1.0]), slot, c, 2.0) == pytest.approx(math.sqrt(2) + math.pi)
    assert route_distance(slot, slot, c, 2.0) == pytest.approx(0.0)
