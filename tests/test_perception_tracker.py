"""Ground-plane Kalman tracker: ids through crossings, gating, birth/deletion, ego-motion, timing."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from ssbl_pb.perception.tracking.tracker import Tracker, TrackerParams, cv_matrices

DT = 0.1


def crossing_scene(steps=80, noise=0.05, seed=0):
    """Four walkers: two pairs crossing at angles, each pair meeting mid-way; (steps, 4, 2) truth + noisy."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps)[:, None] * DT
    starts = np.array([[-4.0, 0.0], [4.0, 0.3], [0.0, -4.0], [1.5, 4.0]])
    vels = np.array([[1.0, 0.0], [-1.0, 0.0], [0.2, 1.0], [-0.2, -1.0]])
    truth = starts[None] + t[..., None] * vels[None]
    return truth, truth + rng.normal(0, noise, truth.shape)


def id_map(track_log, truth):
    """For each true person, the set of confirmed track ids nearest to it (within 0.5 m) over time."""
    ids = {i: [] for i in range(truth.shape[1])}
    for k, states in enumerate(track_log):
        for i in range(truth.shape[1]):
            best = min(states, key=lambda s: np.hypot(*(s.position - truth[k, i])), default=None)
            if best is not None and np.hypot(*(best.position - truth[k, i])) < 0.5:
                ids[i].append(best.id)
    return ids


def test_cv_matrices():
    f, q = cv_matrices(0.5, 2.0)
    assert f[0, 2] == 0.5 and f[1, 3] == 0.5
    assert q[2, 2] == pytest.approx(0.25 * 4.0)
    assert q[0, 0] == pytest.approx(0.5 ** 4 / 4 * 4.0)


def test_crossings_keep_ids():
    truth, meas = crossing_scene()
    trk = Tracker(TrackerParams(dt=DT, meas_std=0.05, accel_std=0.5, birth_hits=3))
    rng = np.random.default_rng(1)
    log = []
    for k in range(len(meas)):
        order = rng.permutation(4)
        log.append(trk.update(meas[k, order]))
    ids = id_map(log, truth)
    for i, seq in ids.items():
        assert len(seq) >= len(truth) - 3, f"person {i} untracked in {len(truth) - len(seq)} frames"
        assert len(set(seq)) == 1, f"person {i} changed id: {sorted(set(seq))}"
    final = {s.id: s for s in log[-1]}
    assert len(final) == 4
    for i in range(4):
        st = final[ids[i][-1]]
        assert np.hypot(*(st.position - truth[-1, i])) < 0.1
        vel_true = (truth[1, i] - truth[0, i]) / DT
        assert np.hypot(*(st.velocity - vel_true)) < 0.2
        assert st.covariance.shape == (4, 4) and np.all(np.linalg.eigvalsh(st.covariance) > 0)
        assert st.age == len(truth) - 1


def test_birth_after_m_hits_and_deletion_after_k_misses():
    p = TrackerParams(dt=DT, birth_hits=3, max_misses=4)
    trk = Tracker(p)
    assert trk.update(np.array([[1.0, 1.0]])) == []
    assert trk.update(np.array([[1.0, 1.0]])) == []
    states = trk.update(np.array([[1.0, 1.0]]))
    assert [s.id for s in states] == [1] and states[0].hits == 3
    for k in range(1, 4):  # coasting: still reported with the miss count
        states = trk.update(np.zeros((0, 2)))
        assert len(states) == 1 and states[0].misses == k
    assert trk.update(np.zeros((0, 2))) == []
    assert trk.tracks == []


def test_tentative_track_dies_on_first_miss():
    trk = Tracker(TrackerParams(birth_hits=3, tentative_misses=1))
    trk.update(np.array([[0.0, 0.0]]))
    trk.update(np.zeros((0, 2)))
    assert trk.tracks == []


def test_gating_rejects_far_detection():
    trk = Tracker(TrackerParams(dt=DT, birth_hits=1, meas_std=0.1, gate=9.21))
    for _ in range(5):
        trk.update(np.array([[0.0, 0.0]]))
    states = trk.update(np.array([[3.0, 0.0]]))  # 3 m jump: outside the gate -> new track, old one coasts
    ids = sorted(s.id for s in states)
    assert ids == [1, 2]
    old = next(s for s in states if s.id == 1)
    assert old.misses == 1 and np.hypot(*old.position) < 0.05


def test_max_jump_keeps_a_young_track_from_a_far_detection():
    """A two-hit track's velocity is unknown (init_vel_std 1 m/s), so after five misses its Mahalanobis gate spans
    metres: a detection 1.5 m away still joins it, unless ``max_jump`` says a person cannot be there."""
    wide = Tracker(TrackerParams(dt=DT, birth_hits=2, meas_std=0.25))
    capped = Tracker(TrackerParams(dt=DT, birth_hits=2, meas_std=0.25, max_jump=1.0))
    for trk in (wide, capped):
        trk.update(np.array([[3.0, 0.0]]))
        trk.update(np.array([[3.0, 0.0]]))
        for _ in range(5):
            trk.update(np.zeros((0, 2)))
    assert [s.id for s in wide.update(np.array([[1.5, 0.0]]))] == [1]  # the far person taken for the near one
    states = capped.update(np.array([[1.5, 0.0]]))
    assert [(s.id, s.misses) for s in states] == [(1, 6)]  # coasting on; the detection starts a tentative track
    assert len(capped.tracks) == 2 and np.hypot(*(capped.tracks[0].kf.x[:2] - [3.0, 0.0])) < 1e-9


def test_max_speed_and_standing_coast():
    """A range that jumps 0.6 m a frame reads as 6 m/s; ``max_speed`` clips it, and with ``coast`` off a missed
    track stands where it was instead of moving on at its last velocity."""
    p = TrackerParams(dt=DT, birth_hits=1, meas_std=0.1, max_speed=0.5, coast=False)
    trk = Tracker(p)
    for x in (3.0, 3.0, 3.0, 2.4):
        states = trk.update(np.array([[x, 0.0]]))
    assert math.isclose(float(np.hypot(*states[0].velocity)), 0.5, rel_tol=1e-9)
    here = states[0].position.copy()
    for _ in range(3):
        states = trk.update(np.zeros((0, 2)))
    assert np.hypot(*(states[0].position - here)) < 0.06  # one frame at <= 0.5 m/s before it was zeroed, then none
    assert np.hypot(*states[0].velocity) == 0.0
    free = Tracker(TrackerParams(dt=DT, birth_hits=1, meas_std=0.1))
    for x in (3.0, 3.0, 3.0, 2.4):
        free.update(np.array([[x, 0.0]]))
    assert np.hypot(*free.states()[0].velocity) > 1.0
    for _ in range(3):
        coasted = free.update(np.zeros((0, 2)))
    assert coasted[0].position[0] < states[0].position[0] - 0.3


def test_ego_motion_compensation():
    """A standing person seen from a robot that drives and turns stays still in the odometry frame."""
    person = np.array([3.0, 1.0])
    trk = Tracker(TrackerParams(dt=DT, meas_std=0.03, accel_std=0.3, birth_hits=2))
    rng = np.random.default_rng(2)
    pose = np.array([0.0, 0.0, 0.0])
    for _k in range(60):
        pose = pose + np.array([0.3 * math.cos(pose[2]) * DT, 0.3 * math.sin(pose[2]) * DT, 0.4 * DT])
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = person - pose[:2]
        local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        states = trk.update(local[None] + rng.normal(0, 0.03, (1, 2)), odom=pose)
    assert len(states) == 1
    st = states[0]
    assert np.hypot(*(st.position - local)) < 0.05  # reported in the robot frame
    assert np.hypot(*st.velocity) < 0.1  # the person is still (the robot's motion is compensated)
    # without odometry the same measurements make the person appear to move
    trk2 = Tracker(TrackerParams(dt=DT, meas_std=0.03, accel_std=0.3, birth_hits=2))
    pose = np.array([0.0, 0.0, 0.0])
    for _k in range(60):
        pose = pose + np.array([0.3 * math.cos(pose[2]) * DT, 0.3 * math.sin(pose[2]) * DT, 0.4 * DT])
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = person - pose[:2]
        local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        states2 = trk2.update(local[None])
    assert np.hypot(*states2[0].velocity) > 0.5


def test_bad_params_and_payloads():
    with pytest.raises(ValueError, match="birth_hits"):
        TrackerParams(birth_hits=0)
    with pytest.raises(ValueError, match="meas_std"):
        TrackerParams(meas_std=-1.0)
    with pytest.raises(ValueError, match="max_jump"):
        TrackerParams(max_jump=0.0)
    with pytest.raises(ValueError, match="max_speed"):
        TrackerParams(max_speed=-0.5)
    with pytest.raises(ValueError, match="coast = 'no'"):
        TrackerParams(coast="no")  # a YAML string is not a switch
    with pytest.raises(ValueError, match="payloads"):
        Tracker().update(np.zeros((2, 2)), payloads=[1])


def test_update_time_five_targets():
    truth, meas = crossing_scene(steps=40)
    meas = np.concatenate([meas, meas[:, :1] + 3.0], axis=1)  # 5 targets
    trk = Tracker(TrackerParams(dt=DT, birth_hits=1))
    for k in range(10):
        trk.update(meas[k])
    t0 = time.perf_counter()
    for k in range(10, 40):
        trk.update(meas[k])
    per = (time.perf_counter() - t0) / 30
    assert len(trk.tracks) == 5
    assert per < 5e-3  # generous on a loaded CI core; the benchmark records the real figure
