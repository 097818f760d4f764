"""Which way the simulated box proxies face, read from Pepper's camera frames (the virtual Pepper's colour
detector); the convention (phi) is ``facing``'s.

A proxy (urdf/human.urdf) is a torso box in the person's colour, 0.26 m deep (along the facing) x 0.46 m wide x
0.60 m tall (0.84-1.44 m above the floor), with a yellow chest plate 0.22 m wide x 0.20 m tall x 0.02 m deep
centred 0.135 m in front of the body axis, 1.19 m up, and a yellow nose (0.05 x 0.04 x 0.04 m, its tip 0.145 m
ahead of the head sphere's centre, 1.58 m up, radius 0.12 m). From a torso box (``x, y, w, h``) and the frame:

- the box's rows give the depth of the torso's nearest corner (as ``ground.boxes_to_ground``);
- its width is the silhouette of the box turned by the facing, 2 (a |sin phi| + b |cos phi|) with a = 0.13, b =
  0.23 m seen from afar: |phi| folded into [0, 90] deg (and not even that near a back: the width peaks 30 deg off);
- the chest plate is seen iff the front faces the camera (|phi| < ~95 deg: it stands 0.015 m proud), and its
  columns relative to the torso box's give sin phi (0.135 m lever) and |cos phi| (its 0.22 m width);
- TinyRenderer shades each face flat by its angle to a light fixed in the world: a vertical colour step inside
  the box is the crease between the two lateral faces seen (the vertical edge nearest the camera), which tells
  how the box is turned, mirror images apart (none shows where both faces are lit alike);
- the nose sticks out beside the head until the head hides it (~135 deg off the line of sight): its side of the
  head tells a person turned left from one turned right, for side views and backs within ~45 deg of side-on.

Each hypothesis phi on a grid (``FacingParams.step_deg``) is rendered with the pinhole camera (perspective,
bearing, the nearest corner at the rows' depth, the axis placed so that the predicted silhouette lines up with
the box), scored against these observations, and the posterior over phi is summarised as a circular mean and
spread. Occlusion is handled: an edge of the box or of the plate next to a nearer person (or the image's side)
only bounds the true one, and a plate not seen where a nearer person covers it does not count against
front-facing hypotheses.

A back seen without a crease or a nose looks like its mirror image about the line of sight: the posterior has
two modes and ``phi`` is their circular mean (pi) with a spread that covers both; ``phi_abs`` keeps the folded
estimate. Where the spread exceeds ``FacingParams.max_std`` (such a back 20-60 deg off square-on, a person mostly
hidden), ``phi`` is NaN; a box whose top or bottom row is out of the frame (a person nearer than ~1.05 m) gets
no estimate at all. Accuracy on rendered frames: tools/bench_facing.py.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import cv2
import numpy as np

from ...params import RobotParams
from ...urdf import HUMAN_COLOURS
from ..camera import PinholeCamera, sim_camera
from .detectors import ColourParams
from .facing import Facing, wrap
from .ground import ProxyGeometry, boxes_to_ground

MARKER_RGB = (0.95, 0.85, 0.10)  # urdf/human.urdf material "marker" (chest plate and nose)


@dataclasses.dataclass(frozen=True)
class ProxyBody:
    """The proxy's shapes that show its facing (urdf/human.urdf), metres in the body frame: x along the facing,
    y to the person's left, z up from the floor."""

    torso_half: tuple[float, float] = (0.13, 0.23)  # torso box 0.26 deep x 0.46 wide
    torso_z: tuple[float, float] = (0.84, 1.44)  # torso joint 0.84 m up, box 0.60 m tall
    marker_x: tuple[float, float] = (0.13, 0.145)  # chest plate 0.02 deep at 0.135: its part in front of the torso
    marker_half_width: float = 0.11  # plate 0.22 wide
    marker_z: tuple[float, float] = (1.09, 1.29)  # plate 0.20 tall, centred 0.35 m above the torso joint
    head_z: float = 1.58  # head sphere's centre (neck joint 0.74 m above the torso joint)
    head_radius: float = 0.12
    nose_x: float = 0.132  # nose box 0.05 deep centred 0.12 ahead of the head's centre: the middle of its part
    # outside the sphere (0.118-0.145)
    nose_tip: float = 0.145
    nose_half: float = 0.02  # nose 0.04 wide and tall


@dataclasses.dataclass(frozen=True)
class FacingParams:
    """Settings of ``estimate_facing`` (pixel errors measured on QVGA TinyRenderer frames, tools/bench_facing.py)."""

    step_deg: float = 1.0  # hypothesis grid
    edge_px: float = 0.5  # std of an edge's column (pixel quantisation)
    scale_rel: float = 0.015  # relative std of predicted sizes (the rows' depth is quantised to a pixel)
    marker_hue_tol: int = 4  # OpenCV hue units around MARKER_RGB's (26.5); orange torsos are at 15
    miss_cost: float = 30.0  # cost (-2 log likelihood) of a plate predicted >= 2 px wide but not seen, or vice versa
    nose_cost: float = 12.0  # cost of a nose seen where the head would hide it (another's head may be there)
    floor_deg: float = 2.0  # model error added to the posterior's spread
    max_std: float = 0.6  # rad (34 deg): a wider posterior (two modes far apart) leaves phi NaN

    def __post_init__(self) -> None:
        if not 0 < self.step_deg <= 10:
            raise ValueError(f"step_deg = {self.step_deg!r}: expected in (0, 10]")
        if self.edge_px <= 0 or self.scale_rel < 0 or self.max_std <= 0:
            raise ValueError("edge_px and max_std must be positive, scale_rel non-negative")


def palette_hues(palette: Sequence[Sequence[float]]) -> np.ndarray:
    """OpenCV hues (0-180) of RGB colours (0-1)."""
    rgb = np.clip(np.asarray(palette, dtype=float)[:, :3] * 255, 0, 255).astype(np.uint8)[None]
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[0, :, 0].astype(int)


class HueMasks:
    """Saturated pixels (``ColourParams`` thresholds) of a frame near given hues (0-180), each mask made once."""

    def __init__(self, hsv: np.ndarray, p: ColourParams) -> None:
        self.hue = hsv[..., 0]
        self.sat = (hsv[..., 1] >= p.min_saturation) & (hsv[..., 2] >= p.min_value)
        self._cache: dict[tuple[int, int], np.ndarray] = {}

    def __call__(self, hue: int, tol: int) -> np.ndarray:
        key = (int(hue), int(tol))
        if key not in self._cache:
            d = np.abs(np.arange(256) - key[0])
            lut = np.minimum(d, 180 - d) <= key[1]  # OpenCV hues wrap at 180
            self._cache[key] = lut[self.hue] & self.sat
        return self._cache[key]


def box_colours(masks: list[np.ndarray], boxes: np.ndarray) -> np.ndarray:
    """Which colour mask each box was cut from: the one whose pixels inside the box (1 px margin) have the box's
    own bounds (a nearer person inside a farther one's box is narrower than that box)."""
    out = np.full(len(boxes), -1)
    for i, (x, y, w, h) in enumerate(np.asarray(boxes, dtype=float)[:, :4]):
        x0, y0, x1, y1 = int(x) - 1, int(y) - 1, int(x + w) + 1, int(y + h) + 1
        best = -1.0
        for c, m in enumerate(masks):
            ys, xs = np.nonzero(m[max(y0, 0):y1, max(x0, 0):x1])
            if not len(xs):
                continue
            bx0, by0 = xs.min() + max(x0, 0), ys.min() + max(y0, 0)
            bx1, by1 = xs.max() + max(x0, 0) + 1, ys.max() + max(y0, 0) + 1
            iw = max(0.0, min(bx1, x + w) - max(bx0, x))
            ih = max(0.0, min(by1, y + h) - max(by0, y))
            iou = iw * ih / ((bx1 - bx0) * (by1 - by0) + w * h - iw * ih)
            if iou > best:
                best, out[i] = iou, c
    return out


def _circ(p: np.ndarray, grid: np.ndarray) -> tuple[float, float]:
    """Circular mean and spread sqrt(-2 ln R) of weights ``p`` on angles ``grid``."""
    z = (p * np.exp(1j * grid)).sum() / p.sum()
    r = min(abs(z), 1.0)
    return float(np.angle(z)), float(math.sqrt(-2.0 * math.log(r)) if r > 1e-12 else math.inf)


class _Scene:
    """One frame's masks: the palette colours of the boxes and the chest plates' connected components."""

    def __init__(self, rgb: np.ndarray | None, masks: HueMasks, boxes: np.ndarray, colours: np.ndarray,
                 palette: Sequence[Sequence[float]], p: FacingParams, cp: ColourParams, body: ProxyBody,
                 g: ProxyGeometry) -> None:
        hues = palette_hues(palette)
        self.rgb, self.body, self.geometry = rgb, body, g
        self.nose: list[float | None] = [None] * len(boxes)  # see assign_noses
        self.height, self.width = masks.hue.shape
        self.boxes, self.colours = boxes, colours
        self.masks = {int(c): masks(hues[c], cp.hue_tol) for c in set(colours.tolist()) if c >= 0}
        marker = masks(int(palette_hues([MARKER_RGB])[0]), p.marker_hue_tol).astype(np.uint8)
        n, self.labels, self.stats, _ = cv2.connectedComponentsWithStats(marker, connectivity=8)
        self.owner = np.full(n, -1)  # box index of each marker component
        for k in range(1, n):
            self.owner[k] = self._owner(k)
        # yellow no torso owns: noses, and plates of two people run together (a side-on plate standing proud of a
        # nearer torso next to a farther one's): it may hide a plate or an edge, so it bounds, never counts
        self.unowned = (self.owner < 0)[self.labels] & (self.labels > 0)

    def assign_noses(self, cam: PinholeCamera) -> None:
        """``self.nose[i]``: the column of box ``i``'s nose, a yellow component no torso owns, within a head's
        radius (plus the nose) of the box's middle and at the head's height, or None."""
        free = [k for k in range(1, len(self.owner)) if self.owner[k] < 0]
        if not free:
            return
        body, c = self.body, cam.centre()[:2]
        adj = self.boxes[:, :4].astype(float).copy()
        adj[:, 1] -= 0.5
        adj[:, 3] += 1.0
        ground = boxes_to_ground(cam, adj, self.geometry, torso=True)
        best: dict[int, tuple[float, int]] = {}
        for i, xy in enumerate(ground):
            if not np.isfinite(xy).all() or self.colours[i] < 0:
                continue
            rng = float(np.hypot(*(xy - c)))
            axis = xy + 0.2 * (xy - c) / max(rng, 1e-6)  # the body axis: ~0.2 m behind the ground point
            dist = rng + 0.2
            head_v = cam.robot_to_pixel(np.array([[*axis, body.head_z]]))[0, 1]
            # the head is above the torso's middle; where an edge is hidden, anywhere the silhouette's middle may be
            # (its width is 0.26-0.53 m: 2a to the diagonal)
            L, R = self.boxes[i, 0] - 0.5, self.boxes[i, 0] + self.boxes[i, 2] - 0.5
            wmin = cam.fx * 2 * body.torso_half[0] / dist
            wmax = cam.fx * 2 * math.hypot(*body.torso_half) / dist
            left_ok, right_ok = self.edges(i, self.blocked(i))
            if left_ok == right_ok:
                span = (0.5 * (L + R), 0.5 * (L + R)) if left_ok else (L, R)
            else:
                span = (L + 0.5 * wmin, L + 0.5 * wmax) if left_ok else (R - 0.5 * wmax, R - 0.5 * wmin)
            reach_u = cam.fx * (body.head_radius + 0.035) / dist + 2.0
            reach_v = cam.fx * 0.06 / dist + 2.0
            for k in free:
                x, y, w, h, _ = self.stats[k]
                cu = x + 0.5 * w - 0.5
                du = max(span[0] - cu, cu - span[1], 0.0) / reach_u
                dv = abs(y + 0.5 * h - 0.5 - head_v) / reach_v
                if du <= 1.0 and dv <= 1.0 and du + dv < best.get(k, (math.inf, -1))[0]:
                    best[k] = (du + dv, i)
        for k, (_, i) in sorted(best.items(), key=lambda kv: kv[1][0]):  # the best match of each box
            if self.nose[i] is None:
                self.nose[i] = self.stats[k][0] + 0.5 * self.stats[k][2] - 0.5

    def blocked(self, i: int) -> np.ndarray:
        """What may hide part of box ``i``: nearer people (torsos and plates) and yellow no one owns."""
        return self.nearer(i) | self.unowned

    def edges(self, i: int, blocked: np.ndarray) -> tuple[bool, bool]:
        """Whether box ``i``'s left and right edges are the torso's own: not next to ``blocked`` or the image's
        side (else the torso may reach further)."""
        x, y, w, h = (int(round(v)) for v in self.boxes[i, :4])
        return (_side_free(blocked, (y, y + h), (x - 2, x)) and x > 1,
                _side_free(blocked, (y, y + h), (x + w, x + w + 2)) and x + w < self.width - 1)

    def nearer(self, i: int) -> np.ndarray:
        """Mask of the people nearer than box ``i`` (taller boxes: the rows span the nearest corner's depth), their
        torsos and chest plates."""
        out = np.zeros((self.height, self.width), dtype=bool)
        closer = [j for j, c in enumerate(self.colours) if j != i and c >= 0 and self.boxes[j, 3] > self.boxes[i, 3]]
        for j in closer:
            out |= self.masks[int(self.colours[j])]
        if closer and (plates := np.isin(self.owner, closer)).any():
            out |= plates[self.labels]
        return out

    def plate_rows(self, i: int) -> tuple[float, float]:
        """Rows where box ``i``'s plate would be (fractions of the torso's height at its nearest corner)."""
        y, h = self.boxes[i, 1] - 0.5, self.boxes[i, 3]
        top, z = self.geometry.torso[1], self.body.marker_z
        span = top - self.geometry.torso[0]
        return y + h * (top - z[1]) / span, y + h * (top - z[0]) / span

    def _owner(self, k: int) -> int:
        """The box a plate component belongs to: one whose colour touches it and whose plate rows match it best."""
        x, y, w, h, _ = self.stats[k]
        x0, y0, x1, y1 = max(x - 2, 0), max(y - 2, 0), min(x + w + 2, self.width), min(y + h + 2, self.height)
        comp = self.labels[y0:y1, x0:x1] == k
        ring = cv2.dilate(comp.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~comp
        best, owner = math.inf, -1
        for i, c in enumerate(self.colours):
            if c < 0 or not (self.masks[int(c)][y0:y1, x0:x1] & ring).any():
                continue
            bx, bw, bh = self.boxes[i, 0], self.boxes[i, 2], self.boxes[i, 3]
            proud = max(2.0, 0.03 * bh / 0.6)  # the plate stands 0.015 m proud of the torso: px at its scale
            if x < bx - proud or x + w - 1 > bx + bw - 1 + proud:  # reaching out of the box: someone else's
                continue
            top, bottom = self.plate_rows(i)
            miss = abs(y - 0.5 - top) + abs(y + h - 0.5 - bottom)
            if miss < best and miss < 0.15 * self.boxes[i, 3] + 3:
                best, owner = miss, i
        return owner


def _columns(cam: PinholeCamera, pts: np.ndarray) -> np.ndarray:
    """Image columns (float) of robot-frame points (..., 3) (the pinhole directly when there is no distortion)."""
    flat = pts.reshape(-1, 3)
    if np.any(cam.dist != 0):
        return cam.robot_to_pixel(flat)[:, 0].reshape(pts.shape[:-1])
    pc = (flat - cam.centre()[None]) @ cam.rotation()
    k = cam.K
    return ((k[0, 0] * pc[:, 0] + k[0, 1] * pc[:, 1]) / pc[:, 2] + k[0, 2]).reshape(pts.shape[:-1])


def _hypotheses(cam: PinholeCamera, box: np.ndarray, grid: np.ndarray, body: ProxyBody,
                g: ProxyGeometry) -> dict[str, np.ndarray] | None:
    """For each phi in ``grid``, the axis placed at the rows' depth on the box's central ray, and the predicted
    columns (float pixels, continuous edges) there: silhouette ``L``/``R``, plate ``mL``/``mR``, the crease
    between the two lateral faces seen (the nearest vertical edge) ``crease``."""
    adj = box[:4].astype(float).copy()
    adj[1] -= 0.5  # the torso's edges are the outer edges of the first and last rows (as deploy's Perception)
    adj[3] += 1.0
    p0 = boxes_to_ground(cam, adj[None], g, torso=True)[0]
    if not np.isfinite(p0).all():
        return None
    c = cam.centre()
    u = (p0 - c[:2]) / max(float(np.hypot(*(p0 - c[:2]))), 1e-6)  # line of sight
    fyaw = math.atan2(-u[1], -u[0]) + grid  # facing yaw of each hypothesis
    f = np.stack([np.cos(fyaw), np.sin(fyaw)], axis=1)  # (k, 2)
    left = np.stack([-f[:, 1], f[:, 0]], axis=1)
    a, b = body.torso_half
    mx0, mx1 = body.marker_x
    mw = body.marker_half_width
    shape = np.array([[a, b], [a, -b], [-a, b], [-a, -b],  # torso corners, then the plate's front part
                      [mx0, mw], [mx0, -mw], [mx1, mw], [mx1, -mw]])
    off = shape[None, :, 0, None] * f[:, None] + shape[None, :, 1, None] * left[:, None]  # (k, 8, 2)
    # the rows see the nearest corner (smallest depth along the camera's axis, robot x): the axis is behind it
    near = off[:, :4, 0].argmin(axis=1)
    depth = -off[np.arange(len(grid)), near, 0]
    axis = np.stack([p0[0] + depth, p0[1] + depth * u[1] / u[0]], axis=1)
    zz = np.array([g.torso] * 4 + [body.marker_z] * 4)  # (8, 2): the heights each point is seen at

    def project(ax: np.ndarray) -> np.ndarray:  # (k, 8 points, 2 heights) columns
        xy = np.broadcast_to((ax[:, None] + off)[:, :, None, :], (len(grid), 8, 2, 2))
        return _columns(cam, np.concatenate([xy, np.broadcast_to(zz[None, :, :, None], (len(grid), 8, 2, 1))], axis=3))

    cols = project(axis)
    # line the silhouette's middle up with the box's (the axis is not on the central ray of a turned box)
    mid = 0.5 * (cols[:, :4].min(axis=(1, 2)) + cols[:, :4].max(axis=(1, 2)))
    shift = (mid - (box[0] + 0.5 * box[2] - 0.5)) * (axis[:, 0] - c[0]) / cam.fx  # +u is -y (right)
    axis = axis + shift[:, None] * np.array([0.0, 1.0])[None]
    cols = project(axis)
    to_cam = c[None, :2] - (axis + body.marker_x[1] * f)
    to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
    facing_cam = (to_cam * f).sum(axis=1)
    # the plate's front faces the camera, or the side of its 0.015 m proud of the torso's face still shows past
    # the torso's front edge (0.12 m further out): up to 97 deg, as a strip of the two corners on that side
    seen = facing_cam > -0.12
    torso, plate = cols[:, :4], cols[:, 4:]
    side = np.where(((to_cam * left).sum(axis=1) > 0)[:, None], [0, 2], [1, 3])  # plate corners on the camera's side
    strip = plate[np.arange(len(grid))[:, None], side]
    edge_on = facing_cam <= 0
    mL = np.where(edge_on, strip.min(axis=(1, 2)), plate.min(axis=(1, 2)))
    mR = np.where(edge_on, strip.max(axis=(1, 2)), plate.max(axis=(1, 2)))
    # the crease is the corner the two faces seen share: the one nearest the camera (not the one of smallest
    # depth along the optical axis, which sets the rows: off the axis they differ)
    closest = np.linalg.norm(axis[:, None] + off[:, :4] - c[None, None, :2], axis=2).argmin(axis=1)
    crease = torso[np.arange(len(grid)), closest].mean(axis=1)
    # the nose shows unless the head hides it: its tip's corner nearest the camera (0.145 m ahead, 0.02 m aside
    # and below) is out of the head sphere's shadow, P.v > -sqrt(|P|^2 - r^2) with v toward the camera: up to
    # 132-138 deg off the line of sight (the camera looks up at the head)
    head = np.concatenate([axis, np.full((len(grid), 1), body.head_z)], axis=1)
    nose = _columns(cam, head + np.concatenate([body.nose_x * f, np.zeros((len(grid), 1))], axis=1))
    v = c[None] - head
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    tip, half = body.nose_tip, body.nose_half
    aside = np.where(((v[:, :2] * left).sum(axis=1) > 0)[:, None], left, -left)
    corner = np.concatenate([tip * f + half * aside, np.full((len(grid), 1), -half)], axis=1)
    reach = math.sqrt(max(tip**2 + 2 * half**2 - body.head_radius**2, 0.0))
    nose_seen = (corner * v).sum(axis=1) > -reach
    return {"L": torso.min(axis=(1, 2)), "R": torso.max(axis=(1, 2)), "mL": mL, "mR": mR, "crease": crease,
            "seen": seen, "depth": depth / u[0], "nose": nose, "nose_seen": nose_seen}


def find_crease(rgb: np.ndarray, own: np.ndarray, box: np.ndarray, min_step: int = 2,
                min_share: float = 0.6) -> float | None:
    """Column (float, between two pixels) of a vertical colour step inside a torso box: the crease between the
    two lateral faces seen, which TinyRenderer shades flat, each by its own angle to the light. ``own``: the
    person's colour mask; only pairs of adjacent own pixels count. None when no column steps in at least
    ``min_share`` of the rows (one face seen, or two lit alike)."""
    x, y, w, h = (int(round(v)) for v in box[:4])
    x0, y0 = max(x, 0), max(y, 0)
    if w < 4 or h < 4:
        return None
    patch = rgb[y0:y + h, x0:x + w].astype(np.int16)
    m = own[y0:y + h, x0:x + w]
    both = m[:, 1:] & m[:, :-1]
    step = (np.abs(np.diff(patch, axis=1)).sum(axis=2) >= min_step) & both
    rows = np.maximum(both.sum(axis=0), 1)
    hits = step.sum(axis=0)
    share = hits / rows
    j = int(np.argmax(hits))
    if hits[j] < max(3, 0.3 * h) or share[j] < min_share:
        return None
    return x0 + j + 0.5


def _side_free(blocked: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> bool:
    """Whether columns ``cols`` (clipped) in ``rows`` hold none of ``blocked`` and lie inside the image."""
    h, w = blocked.shape
    c0, c1 = cols
    if c0 < 0 or c1 > w:
        return False
    return not blocked[max(rows[0], 0):min(rows[1], h), c0:c1].any()


def _one(scene: _Scene, i: int, cam: PinholeCamera, grid: np.ndarray, p: FacingParams, body: ProxyBody,
         g: ProxyGeometry) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """Cost (-2 log likelihood) of each hypothesis for box ``i``, the predicted depths and whether a plate was seen."""
    box = scene.boxes[i]
    hyp = _hypotheses(cam, box, grid, body, g)
    if hyp is None or scene.colours[i] < 0:
        return None
    nearer = scene.blocked(i)
    # an edge next to a nearer person (or yellow no one owns) or the image's side only bounds the silhouette
    left_ok, right_ok = scene.edges(i, nearer)
    L, R = box[0] - 0.5, box[0] + box[2] - 0.5
    cost = np.zeros(len(grid))
    sig_w = math.hypot(p.edge_px * math.sqrt(2), p.scale_rel * box[2])
    pw = hyp["R"] - hyp["L"]
    mid_pred = 0.5 * (hyp["L"] + hyp["R"])
    if left_ok and right_ok:
        cost += ((pw - box[2]) / sig_w) ** 2
        anchor = np.zeros(len(grid))  # predicted columns are already lined up on the box's middle
    elif left_ok or right_ok:  # line up on the edge that is seen; the other may reach further
        anchor = (L - hyp["L"]) if left_ok else (R - hyp["R"])
        cost += (np.maximum(0.0, box[2] - pw) / sig_w) ** 2
    else:
        anchor = None  # no edge to measure the plate from: only whether it is seen counts
    nose = scene.nose[i]
    if nose is not None:  # the head is above the axis: the nose's side of it tells left from right to ~135 deg
        # (a nose not seen counts for nothing: small, and another's head may hide it)
        dist = cam.fx * (g.torso[1] - g.torso[0]) / max(box[3], 1.0)
        sig_n = math.hypot(p.edge_px * 2, cam.fx * 0.01 / dist)
        if anchor is not None:
            cost += np.where(hyp["nose_seen"], ((hyp["nose"] + anchor - nose) / sig_n) ** 2, p.nose_cost)
        else:  # no edge to line the head up with: only that it shows
            cost += np.where(hyp["nose_seen"], 0.0, p.nose_cost)
    mL, mR = hyp["mL"], hyp["mR"]
    if anchor is not None:
        mL, mR = mL + anchor, mR + anchor
        crease = find_crease(scene.rgb, scene.masks[int(scene.colours[i])], box) if scene.rgb is not None else None
        if crease is not None:  # the nearest vertical edge: where one face meets the other
            sig_c = math.hypot(p.edge_px, p.scale_rel * abs(crease - (box[0] + 0.5 * box[2] - 0.5)))
            cost += ((hyp["crease"] + anchor - crease) / sig_c) ** 2
    seen_w = np.where(hyp["seen"], mR - mL, 0.0)
    comps = np.flatnonzero(scene.owner == i)
    marker = len(comps) > 0
    if marker:
        st = scene.stats[comps]
        oL = float(st[:, 0].min()) - 0.5
        oR = float((st[:, 0] + st[:, 2]).max()) - 0.5
        ry0, ry1 = int(st[:, 1].min()), int((st[:, 1] + st[:, 3]).max())
        cost += np.where(hyp["seen"], 0.0, p.miss_cost)
        if anchor is not None:
            sig = np.hypot(p.edge_px * 1.25, p.scale_rel * np.abs(np.array([oL, oR]) - mid_pred[:, None]))
            for k, (obs, pred) in enumerate(((oL, mL), (oR, mR))):
                cols = (int(obs - 1.5), int(obs + 0.5)) if k == 0 else (int(obs + 0.5), int(obs + 2.5))
                d = (pred - obs) / sig[:, k]
                if _side_free(nearer, (ry0, ry1), cols):
                    cost += d**2
                else:  # hidden beyond this edge: the plate may reach further
                    cost += np.where(d * (1 if k == 0 else -1) > 0, d**2, 0.0)
    else:
        # not seen: count it against hypotheses that show it, except where a nearer person covers it or yellow of
        # someone else's lies (this one's plate may have run into it)
        top, bottom = scene.plate_rows(i)
        rows = slice(max(int(top), 0), max(int(math.ceil(bottom)), 1))
        band = (nearer[rows] | (scene.labels[rows] > 0)).any(axis=0)
        cum = np.concatenate([[0], np.cumsum(band)])
        first, last = np.ceil(mL), np.floor(mR)  # the columns whose centres the plate would cover
        a0 = np.clip(first, 0, scene.width).astype(int)
        a1 = np.clip(last + 1, 0, scene.width).astype(int)
        shown = np.maximum(a1 - a0, 0) - (cum[np.maximum(a1, a0)] - cum[a0])  # in the image, not covered
        visible = np.clip(shown / np.maximum(last - first + 1, 1), 0.0, 1.0)
        cost += p.miss_cost * np.clip(seen_w - 1.0, 0.0, 1.0) * visible
    return cost, hyp["depth"], marker


def estimate_facing(frame: np.ndarray | None, boxes: np.ndarray, camera: PinholeCamera | None = None,
                    colours: Sequence[int] | np.ndarray | None = None,
                    palette: Sequence[Sequence[float]] | None = None, params: FacingParams | None = None,
                    hsv: np.ndarray | None = None, colour_params: ColourParams | None = None) -> Facing:
    """Facing of each torso box (``ColourDetector`` / deploy's one-per-colour boxes ``x, y, w, h[, score]``) in an
    RGB ``frame`` (or its ``hsv``, OpenCV's RGB2HSV). ``camera``: the frame's pinhole (default Pepper's simulated
    CameraTop, ``camera.sim_camera``); ``colours``: each box's index in ``palette`` (default the simulator's
    ``HUMAN_COLOURS``; found from the masks when not given)."""
    p = params or FacingParams()
    cp = colour_params or ColourParams()
    boxes = np.asarray(boxes, dtype=float).reshape(-1, np.shape(boxes)[-1] if np.ndim(boxes) == 2 else 5)
    grid = wrap(np.deg2rad(np.arange(-180.0, 180.0, p.step_deg) + p.step_deg))
    grid = np.sort(grid)
    out = Facing.empty(len(boxes), grid)
    if not len(boxes):
        return out
    if hsv is None:
        if frame is None:
            raise ValueError("estimate_facing: give the frame or its hsv")
        hsv = cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2HSV)
    if palette is None:
        palette = HUMAN_COLOURS
    height, width = hsv.shape[:2]
    if camera is None:
        camera = sim_camera(RobotParams(), width, height)
    elif camera.width != width:
        camera = camera.scaled(width, height)
    masks = HueMasks(hsv, cp)
    if colours is None:
        colours = box_colours([masks(hh, cp.hue_tol) for hh in palette_hues(palette)], boxes)
    body, g = ProxyBody(), ProxyGeometry()
    scene = _Scene(frame, masks, boxes, np.asarray(colours, dtype=int), palette, p, cp, body, g)
    scene.assign_noses(camera)
    floor = math.radians(p.floor_deg)
    for i in range(len(boxes)):
        res = _one(scene, i, camera, grid, p, body, g)
        if res is None:
            continue
        cost, depth, marker = res
        post = np.exp(-0.5 * (cost - cost.min()))
        post /= post.sum()
        out.posterior[i], out.marker[i] = post, marker
        mean, spread = _circ(post, grid)
        out.std[i] = math.hypot(spread, floor)
        out.phi[i] = mean if out.std[i] <= p.max_std else np.nan
        folded = np.abs(grid)
        out.phi_abs[i], spread = _circ(post, folded)
        out.phi_abs[i] = abs(out.phi_abs[i])
        out.abs_std[i] = math.hypot(spread, floor)
        out.front[i] = float(post[folded < math.pi / 2].sum())
        out.depth[i] = float((post * depth).sum())
    return out
