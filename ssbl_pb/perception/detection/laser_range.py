"""A detected person's range from the base's lasers: the camera gives the bearing well and the range coarsely
(MoveNet's keypoints: 0.1-0.6 m too far at 1-3 m, docs/tracking.md), the lasers the range to what they hit within a
few centimetres but not whose it is. Pure geometry on robot-frame points.

Each person's laser returns are those within their half-width of the camera's bearing (at the return's range) and
within the gate of the camera's range (wider on the near side: the keypoints' range runs too far); the one nearest
the camera's range is theirs (a nearer one may be someone in front of them), the nearest return up to a body's
depth in front of it their near side, and the person's centre lies ``depth`` behind that, at the mean bearing of
their returns (those around the nearest, across their width: the camera's bearing of a person cut by the image's
bottom is a few degrees off).
"""

from __future__ import annotations

import math

import numpy as np

# m: from the near side a base laser hits (0.03-0.09 m up: the feet and shins, ``deploy.ranges``) to a person's
# centre: a shin's 0.05 m radius and the foot ahead of it; ours, from a 0.26 m foot and the ankle a quarter of it
# from the heel. The virtual Pepper's lasers hit its people's 0.28 m collision cylinder and say so
# (``SimRobot.identity``)
LEG_DEPTH_M = 0.1
HALF_WIDTH_M = 0.25  # m: half a person's width across the line of sight at the lasers' height (feet apart, the
#   cylinder's 0.28 m less the bearing's error)
BODY_DEPTH_M = 0.3  # m: returns this far behind a person's nearest are still theirs (a leg behind the other)
GATE_MIN_M, GATE_REL = 0.5, 0.3  # a return counts within max(0.5 m, 30 % of the camera's range) beyond it: the
#   keypoints' range is up to 0.6 m off at the median at 1 m (docs/tracking.md)
GATE_NEAR_REL = 0.65  # and within 65 % of it nearer: the keypoints' range runs too far, by up to 1.1 m at 2-3 m,
#   and 1.5-1.9 m for a body cut by the image or hidden behind someone (virtual Pepper, lockstep: a member 1.6 m away
#   ranged at 3.1 m, and one 1.7 m away behind another at 1.15 m ranged at 3.0 m, stood as phantoms 1.3-1.5 m behind
#   the members for a minute). A nearer return that is someone in front puts the person onto them, where the tracker
#   starts no second track (``TRACKER_KEYPOINTS.min_new_dist``), not 1.5 m behind them (docs/deploy.md)


def laser_ranged(xy: np.ndarray, points: np.ndarray, depth: float = LEG_DEPTH_M) -> tuple[np.ndarray, np.ndarray]:
    """People at robot-frame ``xy`` (n, 2; NaN unknown) ranged again by laser returns ``points`` (k, 2, robot
    frame): each put ``depth`` behind its near side (the return within its half-width and the gates nearest its range,
    and the nearest a body's depth in front of that), at its returns' mean bearing (module docstring). Returns the
    positions (n, 2) and which were ranged by a laser (n,)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2).copy()
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    hit = np.zeros(len(xy), dtype=bool)
    if not len(pts) or not len(xy):
        return xy, hit
    rho = np.hypot(pts[:, 0], pts[:, 1])
    beta = np.arctan2(pts[:, 1], pts[:, 0])
    for i, (x, y) in enumerate(xy):
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        r, theta = math.hypot(x, y), math.atan2(y, x)
        off = np.abs(np.remainder(beta - theta + math.pi, 2 * math.pi) - math.pi)
        gap = rho + depth - r
        near = (off <= np.arctan2(HALF_WIDTH_M, np.maximum(rho, 0.1))) \
            & (gap <= max(GATE_MIN_M, GATE_REL * r)) & (-gap <= max(GATE_MIN_M, GATE_NEAR_REL * r))
        if near.any():
            # the return nearest the camera's range is this person's (a nearer one may be someone in front),
            # their near side the nearest return at most a body's depth in front of it
            k0 = int(np.flatnonzero(near)[np.argmin(np.abs(gap[near]))])
            body = near & (rho >= rho[k0] - BODY_DEPTH_M)
            k = int(np.flatnonzero(body)[np.argmin(rho[body])])
            # the person's returns: around the nearest, across their width and no deeper than their body
            own = (np.abs(np.remainder(beta - beta[k] + math.pi, 2 * math.pi) - math.pi)
                   <= math.atan2(HALF_WIDTH_M, rho[k])) & (rho <= rho[k] + BODY_DEPTH_M)
            theta = beta[k] + float(np.mean(np.remainder(beta[own] - beta[k] + math.pi, 2 * math.pi) - math.pi))
            rng = float(rho[k]) + depth
            xy[i] = rng * math.cos(theta), rng * math.sin(theta)
            hit[i] = True
    return xy, hit

