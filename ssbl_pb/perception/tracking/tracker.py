"""Multi-target tracker on the ground plane: one constant-velocity Kalman filter per track.

Association uses the Mahalanobis distance of each detection to each track's predicted measurement, gated by a
chi-square threshold and solved with the Hungarian algorithm. Tracks are born tentative, confirmed after
``birth_hits`` hits and deleted after ``max_misses`` consecutive misses (tentative ones after
``tentative_misses``). With scores, weak detections (below ``birth_score``) are matched in a second pass to
the tracks the strong ones left, and start no track (as in ByteTrack).

Given the robot's odometry (x, y, yaw) with each update, detections in the robot frame are moved into the
odometry frame, filtered there (so the robot's own motion is not mistaken for the humans'), and reported back
in the robot frame; reported velocities are the odometry-frame velocities expressed in the robot's axes.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment

from ...errors import UserError

_BIG = 1e9


@dataclasses.dataclass(frozen=True)
class TrackerParams:
    """Tracker settings; defaults suit people walking at up to ~2 m/s observed at 7-30 Hz."""

    dt: float = 0.1  # s between updates (used when ``update`` gets no dt)
    accel_std: float = 1.5  # m/s^2, white-noise acceleration of the constant-velocity model
    meas_std: float = 0.15  # m, ground-position noise of a detection (when none is given per detection)
    init_vel_std: float = 1.0  # m/s, velocity uncertainty of a new track
    gate: float = 13.8  # chi-square gate on the squared Mahalanobis distance (2 dof; 13.8 = 99.9 %)
    birth_hits: int = 3  # M: hits before a track is confirmed
    max_misses: int = 10  # K: consecutive misses before a confirmed track is deleted
    tentative_misses: int = 1  # consecutive misses before a tentative track is deleted
    min_new_dist: float = 0.0  # m; a detection this close to an existing track starts no new one
    max_jump: float = math.inf  # m; a detection farther than this from a track's prediction is not its (a young
    #                            track's unknown velocity widens the Mahalanobis gate past where a person can be)
    max_speed: float = math.inf  # m/s; a track's velocity is clipped to this (people in a conversation step slowly;
    #                               a detection's range that jumps is not a walk)
    coast: bool = True  # a missed track moves on at its velocity; False: it stands where it was (velocity zeroed)
    birth_score: float = -math.inf  # detections scoring below this only update existing tracks (second
    #                                 association pass, as in ByteTrack); they never start one

    def __post_init__(self) -> None:
        for name in ("dt", "accel_std", "meas_std", "init_vel_std", "gate"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise UserError(f"tracker.{name} = {v!r}: expected a finite number > 0")
        for name in ("birth_hits", "max_misses", "tentative_misses"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise UserError(f"tracker.{name} = {v!r}: expected an integer >= 1")
        for name in ("max_jump", "max_speed"):
            if not getattr(self, name) > 0:
                raise UserError(f"tracker.{name} = {getattr(self, name)!r}: expected > 0 (inf: no limit)")
        if not isinstance(self.coast, bool):
            raise UserError(f"tracker.coast = {self.coast!r}: expected true or false")
        if not self.min_new_dist >= 0:
            raise UserError(f"tracker.min_new_dist = {self.min_new_dist!r}: expected >= 0")


@dataclasses.dataclass
class TrackState:
    """One track as reported: position/velocity (m, m/s) and 4x4 covariance in the output frame."""

    id: int
    position: np.ndarray
    velocity: np.ndarray
    covariance: np.ndarray
    age: int  # updates since birth
    hits: int
    misses: int  # consecutive misses (0 = detected in this update)
    confirmed: bool
    payload: Any = None  # the last associated detection's payload (e.g. its image box)


class _Track:
    def __init__(self, tid: int, z: np.ndarray, r: np.ndarray, p: TrackerParams, payload: Any) -> None:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
        kf.x = np.array([z[0], z[1], 0.0, 0.0])
        kf.P = np.diag([r[0, 0], r[1, 1], p.init_vel_std ** 2, p.init_vel_std ** 2])
        self.kf = kf
        self.id = tid
        self.age = 0
        self.hits = 1
        self.misses = 0
        self.confirmed = p.birth_hits <= 1
        self.payload = payload


def cv_matrices(dt: float, accel_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity transition F and process noise Q (white acceleration) for state (x, y, vx, vy)."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    q1 = np.array([[dt ** 4 / 4, dt ** 3 / 2], [dt ** 3 / 2, dt ** 2]]) * accel_std ** 2
    q = np.zeros((4, 4))
    q[np.ix_([0, 2], [0, 2])] = q1
    q[np.ix_([1, 3], [1, 3])] = q1
    return f, q


def _se2(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([[c, -s], [s, c]]), np.asarray(pose[:2], dtype=float)


class Tracker:
    """Kalman multi-target tracker; ``update`` once per frame with that frame's ground detections."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params or TrackerParams()
        self.tracks: list[_Track] = []
        self._next_id = 1
        self._pose: np.ndarray | None = None  # last odometry pose, for output in the robot frame

    def reset(self) -> None:
        self.tracks = []
        self._next_id = 1
        self._pose = None

    def update(self, detections: np.ndarray, dt: float | None = None, odom: np.ndarray | None = None,
               meas_cov: np.ndarray | None = None, payloads: list[Any] | None = None,
               scores: np.ndarray | None = None) -> list[TrackState]:
        """Predict by ``dt``, associate, correct, manage births/deaths; returns the confirmed tracks.

        detections: (n, 2) ground positions (m), in the robot frame when ``odom`` is given, else world.
        odom: robot pose (x, y, yaw) in the odometry frame at this frame, or None for a static camera.
        meas_cov: (n, 2, 2) per-detection covariance (m^2) in the same frame as the detections, or None.
        payloads: one object per detection kept with the track it updates (e.g. an image box).
        scores: (n,) detection scores compared with ``birth_score``; None = all strong.
        """
        p = self.params
        z = np.asarray(detections, dtype=float).reshape(-1, 2)
        n = len(z)
        if meas_cov is None:
            r_all = np.broadcast_to(np.eye(2) * p.meas_std ** 2, (n, 2, 2)).copy()
        else:
            r_all = np.asarray(meas_cov, dtype=float).reshape(n, 2, 2).copy()
        if payloads is not None and len(payloads) != n:
            raise ValueError(f"payloads: {len(payloads)} items for {n} detections")
        if odom is not None:
            rot, t = _se2(np.asarray(odom, dtype=float))
            z = z @ rot.T + t
            r_all = rot @ r_all @ rot.T
            self._pose = np.asarray(odom, dtype=float).copy()
        f, q = cv_matrices(p.dt if dt is None else dt, p.accel_std)
        for tr in self.tracks:
            tr.kf.predict(F=f, Q=q)
            tr.age += 1
        strong = np.ones(n, dtype=bool) if scores is None else np.asarray(scores, dtype=float) >= p.birth_score
        hi, lo = np.flatnonzero(strong), np.flatnonzero(~strong)
        all_tracks = list(range(len(self.tracks)))
        m1, un_hi = self._associate(z, r_all, hi, all_tracks)
        left = sorted(set(all_tracks) - {t for t, _ in m1})
        m2, _ = self._associate(z, r_all, lo, [t for t in left if self.tracks[t].confirmed])
        matches, unmatched_dets = m1 + m2, un_hi
        matched_tracks = set()
        for ti, di in matches:
            tr = self.tracks[ti]
            tr.kf.update(z[di], R=r_all[di])
            tr.hits += 1
            tr.misses = 0
            tr.confirmed = tr.confirmed or tr.hits >= p.birth_hits
            speed = math.hypot(tr.kf.x[2], tr.kf.x[3])
            if speed > p.max_speed:
                tr.kf.x[2:] *= p.max_speed / speed
            tr.payload = payloads[di] if payloads is not None else None
            matched_tracks.add(ti)
        keep = []
        for ti, tr in enumerate(self.tracks):
            if ti not in matched_tracks:
                tr.misses += 1
                tr.payload = None
                if not p.coast:
                    tr.kf.x[2:] = 0.0
                limit = p.max_misses if tr.confirmed else p.tentative_misses
                if tr.misses >= limit:
                    continue
            keep.append(tr)
        self.tracks = keep
        for di in unmatched_dets:
            if p.min_new_dist > 0 and self.tracks:
                d = min(float(np.hypot(*(tr.kf.x[:2] - z[di]))) for tr in self.tracks)
                if d < p.min_new_dist:
                    continue
            payload = payloads[di] if payloads is not None else None
            self.tracks.append(_Track(self._next_id, z[di], r_all[di], p, payload))
            self._next_id += 1
        return self.states()

    def _associate(self, z: np.ndarray, r_all: np.ndarray, dets: np.ndarray,
                   tracks: list[int]) -> tuple[list[tuple[int, int]], list[int]]:
        """Hungarian matching of detections ``dets`` to tracks ``tracks`` (indices); returns matches as
        (track index, detection index) and the unmatched detection indices."""
        dets = [int(d) for d in dets]
        if not tracks or not dets:
            return [], dets
        zz, rr = z[dets], r_all[dets]
        xs = np.array([self.tracks[t].kf.x[:2] for t in tracks])  # (nt, 2)
        ps = np.array([self.tracks[t].kf.P[:2, :2] for t in tracks])  # (nt, 2, 2)
        s = ps[:, None] + rr[None]  # (nt, nd, 2, 2)
        y = zz[None] - xs[:, None]  # (nt, nd, 2)
        det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
        d2 = (s[..., 1, 1] * y[..., 0] ** 2 - 2 * s[..., 0, 1] * y[..., 0] * y[..., 1]
              + s[..., 0, 0] * y[..., 1] ** 2) / det
        # confirmed tracks are preferred over tentative ones at equal distance
        penalty = np.array([0.0 if self.tracks[t].confirmed else 1.0 for t in tracks])[:, None]
        near = np.hypot(y[..., 0], y[..., 1]) <= self.params.max_jump
        cost = np.where((d2 <= self.params.gate) & near, d2 + penalty, _BIG)
        rows, cols = linear_sum_assignment(cost)
        matches = [(tracks[r], dets[c]) for r, c in zip(rows, cols, strict=True) if cost[r, c] < _BIG]
        used = {d for _, d in matches}
        return matches, [d for d in dets if d not in used]

    def states(self, include_tentative: bool = False) -> list[TrackState]:
        """Current tracks, in the robot frame when the last update had odometry."""
        out = []
        for tr in self.tracks:
            if not (tr.confirmed or include_tentative):
                continue
            x = tr.kf.x.copy()
            cov = tr.kf.P.copy()
            if self._pose is not None:
                rot, t = _se2(self._pose)
                x[:2] = rot.T @ (x[:2] - t)
                x[2:] = rot.T @ x[2:]
                big = np.zeros((4, 4))
                big[:2, :2] = big[2:, 2:] = rot.T
                cov = big @ cov @ big.T
            out.append(TrackState(tr.id, x[:2], x[2:], cov, tr.age, tr.hits, tr.misses, tr.confirmed,
                                  tr.payload))
        return out
