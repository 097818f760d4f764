"""A person's ground position from a box when the feet may be out of sight: head-and-shoulders ranging.

Two cues, chosen per box:

- **feet**: the box's bottom centre on the ground plane (z = 0), used when the bottom edge is inside the image,
  the body height the box then implies (head row against the foot point) is plausible (1.3-2.1 m) and the box is
  not too wide for a whole person (``max_aspect``, width / height; off by default);
- **head**: otherwise (the feet below the image, hidden behind something, or cut off by the detector). Where
  the detector gives keypoints (MoveNet, whose boxes start at the eyes, not the head top) and ``keypoints`` is
  on, the head's, shoulders' and hips' rows (and the shoulders' width) range the person
  (``keypoints.range_keypoints``). Else the box's top centre is taken as the head top: its ray meets the plane
  at the prior person height (``person_height``); the box's width (``box_width`` m across the line of sight at
  half that height, the same detector's boxes around a whole person) gives the range along the same ray a
  second time; the two are averaged by their variances (height prior ``height_std``, width prior
  ``width_rel_std``).

Each position carries a covariance (m^2): the pixel noise pushed through the projection's Jacobian (as
``pipeline.ground_covariance``) plus, for the head cue, the fused prior's variance along the line of sight, so
the tracker trusts a head-ranged detection less where the priors matter (far away, the camera near head
height). Works with any camera offering ``image_to_plane(uv, z)`` and ``world_to_image(xyz)``
(``TsaiCamera``-like; ``PinholeGeometry`` adapts ``camera.PinholeCamera``).
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from ...errors import UserError
from ..camera import pixel_to_plane
from .keypoint_range import range_keypoints
from .keypoints import PERSON_HEIGHT, BodyParams

FEET, HEAD = 0, 1  # cue codes returned by ``range_boxes``


class Geometry(Protocol):
    def image_to_plane(self, uv: np.ndarray, z: float) -> np.ndarray:
        """Pixels (n, 2) -> points (n, 2) (m) on the horizontal plane at height ``z``."""
        ...

    def world_to_image(self, xyz: np.ndarray) -> np.ndarray:
        """Points (n, 3) (m) -> pixels (n, 2)."""
        ...

    @property
    def centre_m(self) -> np.ndarray:
        """The camera's optical centre (3,) in the same frame (m)."""
        ...


class TsaiGeometry:
    """``Geometry`` of a ``tsai.TsaiCamera`` (world frame, z up)."""

    def __init__(self, camera: object) -> None:
        self.camera = camera

    def image_to_plane(self, uv: np.ndarray, z: float) -> np.ndarray:
        return self.camera.image_to_ground(np.asarray(uv, dtype=float), z)  # type: ignore[attr-defined]

    def world_to_image(self, xyz: np.ndarray) -> np.ndarray:
        return self.camera.world_to_image(np.asarray(xyz, dtype=float))  # type: ignore[attr-defined]

    @property
    def centre_m(self) -> np.ndarray:
        return np.asarray(self.camera.centre_m, dtype=float)  # type: ignore[attr-defined]


class PinholeGeometry:
    """``Geometry`` of a ``camera.PinholeCamera`` (robot frame: x forward, y left, z up)."""

    def __init__(self, camera: object) -> None:
        self.camera = camera

    def image_to_plane(self, uv: np.ndarray, z: float) -> np.ndarray:
        return pixel_to_plane(self.camera, uv, z)  # type: ignore[arg-type]

    def world_to_image(self, xyz: np.ndarray) -> np.ndarray:
        return self.camera.robot_to_pixel(np.asarray(xyz, dtype=float))  # type: ignore[attr-defined]

    @property
    def centre_m(self) -> np.ndarray:
        return np.asarray(self.camera.centre(), dtype=float)  # type: ignore[attr-defined]


@dataclasses.dataclass(frozen=True)
class RangingParams:
    """Priors of head-and-shoulders ranging. Defaults: PETS S2L1 ground-truth boxes of frames 0-399 (head top
    1.76 m median, 1.67-1.89 m 10th-90th percentile; box width at the feet 0.61 m median)."""

    person_height: float = PERSON_HEIGHT  # m, head top above the floor
    height_std: float = 0.08  # m
    box_width: float = 0.61  # m, the width of the detector's box around a whole person
    width_rel_std: float = 0.25  # relative spread of that width (arms, pose, facing)
    min_body_height: float = 1.3  # m; a foot-ranged box implying a body outside these heights is taken as cut
    max_body_height: float = 2.1  # above the feet (the camera above heads: shorter; near head height: taller)
    edge_margin: float = 2.0  # px; a bottom edge this close to the image's is taken as cut by it
    max_aspect: float = float("inf")  # a box wider than this times its height is taken as cut above the feet
    pixel_noise: float = 0.05  # px noise as a fraction of the box height (feet) or width (head)
    keypoints: bool = True  # a cut person with keypoints (MoveNet) ranged from them, not from the box's top

    def __post_init__(self) -> None:
        for name in ("person_height", "height_std", "box_width", "width_rel_std", "pixel_noise"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise UserError(f"ranging.{name} = {v!r}: expected a finite number > 0")


def implied_height(geom: Geometry, foot_xy: np.ndarray, top_v: np.ndarray) -> np.ndarray:
    """Height (m) of a person standing at ``foot_xy`` (n, 2) whose head top is at image row ``top_v`` (n,)."""
    foot_xy = np.asarray(foot_xy, dtype=float).reshape(-1, 2)
    z0 = np.column_stack([foot_xy, np.zeros(len(foot_xy))])
    lo = geom.world_to_image(z0)[:, 1]
    hi = geom.world_to_image(z0 + [0.0, 0.0, 1.0])[:, 1]
    return (lo - np.asarray(top_v, dtype=float)) / np.maximum(lo - hi, 1e-6)


def _jacobian_cov(geom: Geometry, uv: np.ndarray, z: float, sigma_px: np.ndarray) -> np.ndarray:
    eps = 0.5
    g0 = geom.image_to_plane(uv, z)
    jac = np.stack([(geom.image_to_plane(uv + [eps, 0.0], z) - g0) / eps,
                    (geom.image_to_plane(uv + [0.0, eps], z) - g0) / eps], axis=-1)
    return jac @ jac.transpose(0, 2, 1) * (np.asarray(sigma_px, dtype=float) ** 2)[:, None, None]


def head_ground(geom: Geometry, boxes: np.ndarray, p: RangingParams) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions (n, 2) and covariances (n, 2, 2) from the boxes' head rows and widths (``x, y, w, h``)."""
    boxes = np.asarray(boxes, dtype=float).reshape(-1, boxes.shape[-1] if np.ndim(boxes) == 2 else 4)
    n = len(boxes)
    if n == 0:
        return np.zeros((0, 2)), np.zeros((0, 2, 2))
    u = boxes[:, 0] + boxes[:, 2] / 2.0
    head_uv = np.column_stack([u, boxes[:, 1]])
    c = geom.centre_m[:2]
    # the head cue: the head top's ray at the prior height; its variance along the line of sight from the prior
    a = geom.image_to_plane(head_uv, p.person_height)
    da = geom.image_to_plane(head_uv, p.person_height + p.height_std) - a
    var_a = (da ** 2).sum(axis=1)
    ra = np.hypot(*(a - c).T)
    # the width cue: the box's width against the prior width of a person standing at ``a``, scales the range
    side = np.column_stack([-(a - c)[:, 1], (a - c)[:, 0]]) / np.maximum(ra, 1e-9)[:, None]
    lr = [geom.world_to_image(np.column_stack([a + s * p.box_width / 2 * side, np.full(n, p.person_height / 2)]))
          for s in (-1.0, 1.0)]
    w_pred = np.hypot(*(lr[1] - lr[0]).T)
    rb = ra * w_pred / np.maximum(boxes[:, 2], 1.0)
    var_b = (p.width_rel_std * rb) ** 2
    w = var_b / (var_a + var_b)  # weight of the head cue
    r = w * ra + (1 - w) * rb
    unit = (a - c) / np.maximum(ra, 1e-9)[:, None]
    xy = c + unit * r[:, None]
    var_r = var_a * var_b / (var_a + var_b)
    cov = _jacobian_cov(geom, head_uv, p.person_height, p.pixel_noise * boxes[:, 2])
    cov += var_r[:, None, None] * unit[:, :, None] * unit[:, None, :]
    return xy, cov


def foot_ground(geom: Geometry, boxes: np.ndarray, p: RangingParams) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions (n, 2) and covariances (n, 2, 2) of the boxes' bottom centres (``x, y, w, h``)."""
    boxes = np.asarray(boxes, dtype=float).reshape(-1, boxes.shape[-1] if np.ndim(boxes) == 2 else 4)
    if len(boxes) == 0:
        return np.zeros((0, 2)), np.zeros((0, 2, 2))
    feet = np.column_stack([boxes[:, 0] + boxes[:, 2] / 2.0, boxes[:, 1] + boxes[:, 3]])
    return geom.image_to_plane(feet, 0.0), _jacobian_cov(geom, feet, 0.0, p.pixel_noise * boxes[:, 3])


def _rows(a: np.ndarray | None, n: int, keep: np.ndarray) -> np.ndarray | None:
    return None if a is None else np.asarray(a, dtype=float).reshape(n)[keep]


def range_boxes(geom: Geometry, boxes: np.ndarray, image_height: float, p: RangingParams | None = None,
                keypoints: np.ndarray | None = None, body: BodyParams | None = None, yaw: np.ndarray | None = None,
                yaw_std: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per box: ground position (n, 2), covariance (n, 2, 2) and cue (``FEET`` or ``HEAD``).

    Feet where the bottom edge is inside the image (``edge_margin``), the foot point implies a body between
    ``min_body_height`` and ``max_body_height`` and the box's width / height is at most ``max_aspect``; elsewhere
    the keypoints (n, 17, 3) where given and enough of them seen (``keypoint_range.range_keypoints``, template
    ``body``; each person's facing ``yaw`` (n,; rad, NaN unknown) and its ``yaw_std``, where known, place the
    face ahead of the shoulders and give their width), else the head row and the box's width."""
    p = p or RangingParams()
    boxes = np.asarray(boxes, dtype=float)
    boxes = boxes.reshape(-1, boxes.shape[-1] if boxes.ndim == 2 else 4)
    n = len(boxes)
    xy, cov = foot_ground(geom, boxes, p)
    cue = np.full(n, FEET, dtype=int)
    if n == 0:
        return xy, cov, cue
    cut = boxes[:, 1] + boxes[:, 3] >= image_height - p.edge_margin
    cut |= boxes[:, 2] > p.max_aspect * boxes[:, 3]
    tall = implied_height(geom, xy, boxes[:, 1])
    odd = ~((tall >= p.min_body_height) & (tall <= p.max_body_height))
    head = cut | odd | ~np.isfinite(xy).all(axis=1)
    if head.any():
        hxy, hcov = head_ground(geom, boxes[head], p)
        if keypoints is not None and p.keypoints:
            kxy, kcov, ok = range_keypoints(geom, np.asarray(keypoints, dtype=float)[head], body or BodyParams(),
                                            _rows(yaw, n, head), _rows(yaw_std, n, head))
            hxy[ok], hcov[ok] = kxy[ok], kcov[ok]
        xy[head], cov[head], cue[head] = hxy, hcov, HEAD
    return xy, cov, cue
