"""A person's facing from their body keypoints (COCO's 17, as MoveNet returns them) seen by a calibrated camera:
pure geometry, no network (their range: ``keypoint_range``).

The body is a template of the keypoints whose places do not move with the gait (nose, eyes, ears, shoulders,
hips), in the body frame (x along the facing, y to the person's left, z up from the floor; ``BodyParams``). The
shoulders and hips sit where the line of sight grazes the body's section (``silhouette``): face-on at the joints,
side-on at the chest's front and back, where the network finds them.

- **One frame** (``facing_posterior``): the template is placed at the person's ground position turned to each yaw
  on a grid, projected by the camera (``local_projection``) and fitted to the keypoints seen (a free image shift
  and a scale near 1: the position and the stature need not be exact). What tells the yaw: the direction of the
  shoulder and hip lines in the image and their left and right labels (the network tells a person's left from
  their right by the body, and swaps them now and then: ``swap_rate``, a mixture of both labellings), their
  apparent width against the body's height in pixels, the face's points against the shoulders' (the nose stands
  ahead of them), and, on people large enough for the network to see a face (``face_min_ppm``), whether the
  face's points were found at all (seen: the front faces the camera; not: the back).
- **A track** (``FacingTrack``): a histogram filter over the same grid, so a frame that cannot tell front from back
  adds to whichever the track's other frames back.

Nothing here reads motion: a person walking backwards still faces forward. Cameras: anything with
``world_to_image(xyz)`` and ``centre_m`` (``ranging.Geometry``: ``TsaiGeometry`` for PETS, ``PinholeGeometry``
for Pepper's camera).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from ...errors import UserError

KEYPOINTS = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
             "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
             "right_knee", "left_ankle", "right_ankle")  # COCO order
NOSE, L_EYE, R_EYE, L_EAR, R_EAR, L_SHOULDER, R_SHOULDER = 0, 1, 2, 3, 4, 5, 6
L_HIP, R_HIP = 11, 12
RIGID = (NOSE, L_EYE, R_EYE, L_EAR, R_EAR, L_SHOULDER, R_SHOULDER, L_HIP, R_HIP)  # the template's keypoints
FACE = (NOSE, L_EYE, R_EYE)  # seen only from the front
GROUPS = ((NOSE, L_EYE, R_EYE, L_EAR, R_EAR), (L_SHOULDER, R_SHOULDER), (L_HIP, R_HIP))  # head, shoulders, hips
RIGID_GROUP = np.array([next(g for g, members in enumerate(GROUPS) if k in members) for k in RIGID])
PERSON_HEIGHT = 1.76  # m, head top: PETS S2L1 ground-truth boxes of frames 0-399, median (1.67-1.89 m 10th-90th)


@dataclasses.dataclass(frozen=True)
class BodyParams:
    """The keypoint template and the fit's noise, measured on MoveNet's keypoints of PETS S2L1 frames 0-399 (people
    walking at 0.5 m/s or more, facing where they walk; the heights against the GT foot points, the rest by least
    squares with a left/right swap per person, on close looks: ``movenet.MoveNetDetector.look``): eyes 1.64, nose
    1.60, shoulders 1.42, hips 0.91 m up for a stature of 1.76 m (anthropometric tables: within 0.02 m), the
    shoulders 0.32 m apart, the nose 0.11 m ahead of them; the labels swapped on 9 % of the people."""

    stature: float = PERSON_HEIGHT  # m, head top
    stature_std: float = 0.08  # m (PETS GT: 1.67-1.89 m 10th-90th percentile)
    nose: tuple[float, float, float] = (0.11, 0.0, 1.60)  # m: forward, left, up
    eye: tuple[float, float, float] = (0.093, 0.024, 1.64)  # the left one (the right one mirrored)
    ear: tuple[float, float, float] = (0.028, 0.056, 1.61)
    shoulder: tuple[float, float, float] = (-0.02, 0.16, 1.42)
    hip: tuple[float, float, float] = (-0.035, 0.095, 0.91)
    width_rel_std: float = 0.12  # relative spread of the shoulders' width between people
    min_score: float = 0.2  # a keypoint scoring at least this counts as seen
    pixel_std: float = 1.0  # px: keypoint noise floor
    noise: tuple[float, float, float] = (0.05, 0.075, 0.07)  # m on the body: each keypoint's noise across the
    #   image (head, shoulders, hips) that grows with the person's size (clothes, pose, the network)
    row_noise: tuple[float, float, float] = (0.03, 0.036, 0.055)  # m on the body: the same along the image's rows
    torso_depth: tuple[float, float] = (0.13, 0.13)  # m: half the body's depth at the shoulders and hips (a side
    #   view's shoulders and hips are found on its outline, the chest's front and back: ``silhouette``)
    swap_rate: float = 0.1  # how often the network swaps a person's left and right labels
    scale_std: float = 0.12  # relative: how far the fitted size may stray from the template at the position
    step_deg: float = 5.0  # yaw hypotheses
    floor_deg: float = 8.0  # model error added to the posterior's spread
    max_std_deg: float = 50.0  # a wider posterior (front and back alike) leaves the facing unknown
    mode_halfwidth_deg: float = 60.0  # a track's facing: the mean of its posterior this close to the peak
    face_min_ppm: float = 150.0  # px per metre at the person from which a face's points seen or not count: a
    #   head 35 px tall; PETS people (45 px/m) score face and body points alike whichever way they face
    face_score: float = 0.3  # a face point scoring this is seen
    face_cost: float = 5.0  # -2 log likelihood of a face point seen where the hypothesis hides it, or vice versa
    face_hidden_deg: float = 100.0  # the face's points hide beyond this angle from the line of sight

    def __post_init__(self) -> None:
        for name in ("stature", "stature_std", "pixel_std", "scale_std", "step_deg", "floor_deg", "max_std_deg",
                     "width_rel_std"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise UserError(f"keypoints.{name} = {v!r}: expected a finite number > 0")
        for name in ("noise", "row_noise"):
            v = getattr(self, name)
            if len(v) != len(GROUPS) or not all(math.isfinite(x) and x > 0 for x in v):
                raise UserError(f"keypoints.{name} = {v!r}: expected three numbers > 0 (head, shoulders, hips)")
        if len(self.torso_depth) != 2 or not all(math.isfinite(x) and x > 0 for x in self.torso_depth):
            raise UserError(f"keypoints.torso_depth = {self.torso_depth!r}: expected two numbers > 0 (shoulders, "
                            f"hips)")
        if not 0 <= self.swap_rate < 1:
            raise UserError(f"keypoints.swap_rate = {self.swap_rate!r}: expected in [0, 1)")
        if not 0 <= self.min_score <= 1 or not 0 <= self.face_score <= 1:
            raise UserError(f"keypoints.min_score / face_score = {self.min_score!r} / {self.face_score!r}: "
                            f"expected in [0, 1]")


@functools.lru_cache(maxsize=8)
def template(p: BodyParams) -> np.ndarray:
    """The 17 keypoints in the body frame (17, 3) (m; NaN for the limbs', which move with the gait); read-only."""
    out = np.full((17, 3), np.nan)
    out[NOSE] = p.nose
    for (left, right), pt in (((L_EYE, R_EYE), p.eye), ((L_EAR, R_EAR), p.ear), ((L_SHOULDER, R_SHOULDER), p.shoulder),
                              ((L_HIP, R_HIP), p.hip)):
        out[left] = pt
        out[right] = (pt[0], -pt[1], pt[2])
    out.flags.writeable = False
    return out


def project(geom: object, pts: np.ndarray) -> np.ndarray:
    """Points (..., 3) -> pixels (..., 2) through ``geom.world_to_image`` (which takes (n, 3))."""
    flat = np.asarray(pts, dtype=float).reshape(-1, 3)
    return geom.world_to_image(flat).reshape(pts.shape[:-1] + (2,))  # type: ignore[attr-defined]


def local_projection(geom: object, xy: np.ndarray, heights: np.ndarray,
                     eps: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """The camera around people at ground points ``xy`` (n, 2), at each of ``heights`` (h,) (m): the pixel of the
    body's axis there (n, h, 2) and the Jacobian (n, h, 2, 2) of the pixel against a horizontal displacement (m;
    central differences over ``eps``). A body point ``d`` (m) off the axis projects to ``base + J d`` (the
    neglected term is (|d| / range)^2 of it: 2 % for a shoulder 1 m away)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    n, nh = len(xy), len(heights)
    offs = np.array([[0.0, 0.0], [eps, 0.0], [-eps, 0.0], [0.0, eps], [0.0, -eps]])
    g = xy[:, None, None, :] + offs[None, None]  # (n, 1, 5, 2)
    z = np.broadcast_to(np.asarray(heights, dtype=float)[None, :, None, None], (n, nh, 5, 1))
    px = project(geom, np.concatenate([np.broadcast_to(g, (n, nh, 5, 2)), z], axis=-1))  # (n, h, 5, 2)
    jac = np.stack([(px[:, :, 1] - px[:, :, 2]) / (2 * eps), (px[:, :, 3] - px[:, :, 4]) / (2 * eps)], axis=-1)
    return px[:, :, 0], jac


def silhouette(view: np.ndarray, half_width: float, half_depth: float) -> np.ndarray:
    """The left and right edges (..., 2, 2) (body frame: forward, left; m) of a horizontal elliptical section of the
    body (``half_width`` across, ``half_depth`` along the facing) seen along ``view`` (..., 2) (unit, body frame,
    from the camera toward the body): the points where the line of sight grazes it, ``left`` the one on the
    person's left (+y) side. Face-on they are the joints' places (0, +-w); side-on the chest's front and back
    (+-d, 0), where the network finds a side view's shoulders."""
    vx, vy = view[..., 0], view[..., 1]
    t = np.stack([-vy * half_depth ** 2, vx * half_width ** 2], axis=-1)
    t = t / np.sqrt(vy ** 2 * half_depth ** 2 + vx ** 2 * half_width ** 2)[..., None]
    t = t * np.where(t[..., 1:] >= 0, 1.0, -1.0)
    return np.stack([t, -t], axis=-2)


def predict(geom: object, xy: np.ndarray, yaw: np.ndarray, p: BodyParams) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (n, k, 9, 2) of the template's ``RIGID`` points of people at ground points ``xy`` (n, 2) facing each
    of ``yaw`` (k,) (``local_projection`` at each point's height; the shoulders and hips at their ``silhouette``),
    and the image's rows per metre of height along the body (n,)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    n, k = len(xy), len(yaw)
    body = template(p)[list(RIGID)]
    heights, inv = np.unique(body[:, 2], return_inverse=True)
    base, jac = local_projection(geom, xy, heights)
    c, s = np.cos(yaw), np.sin(yaw)
    cam = np.asarray(geom.centre_m, dtype=float)[:2]  # type: ignore[attr-defined]
    u = xy - cam
    u = u / np.maximum(np.hypot(u[:, 0], u[:, 1]), 1e-9)[:, None]  # (n, 2) line of sight
    view = np.stack([c[None] * u[:, :1] + s[None] * u[:, 1:], -s[None] * u[:, :1] + c[None] * u[:, 1:]], axis=-1)
    bx = np.empty((n, k, len(RIGID)))
    by = np.empty((n, k, len(RIGID)))
    bx[:, :, :5], by[:, :, :5] = body[:5, 0], body[:5, 1]  # the head's points: rigid
    for (left, right), width, depth, fwd in (((5, 6), p.shoulder[1], p.torso_depth[0], p.shoulder[0]),
                                             ((7, 8), p.hip[1], p.torso_depth[1], p.hip[0])):
        edges = silhouette(view, width, depth)  # (n, k, 2, 2)
        bx[:, :, left], by[:, :, left] = edges[:, :, 0, 0] + fwd, edges[:, :, 0, 1]
        bx[:, :, right], by[:, :, right] = edges[:, :, 1, 0] + fwd, edges[:, :, 1, 1]
    cc, ss = c[None, :, None], s[None, :, None]
    dx, dy = cc * bx - ss * by, ss * bx + cc * by  # world frame (n, k, 9)
    j = jac[:, None, inv]  # (n, 1, 9, 2, 2)
    b0 = base[:, None, inv]
    out = np.stack([b0[..., 0] + j[..., 0, 0] * dx + j[..., 0, 1] * dy,
                    b0[..., 1] + j[..., 1, 0] * dx + j[..., 1, 1] * dy], axis=-1)
    ppm = np.abs(base[:, -1, 1] - base[:, 0, 1]) / max(heights[-1] - heights[0], 1e-9)
    return out, ppm


def mode_mean(post: np.ndarray, grid: np.ndarray, halfwidth: float) -> tuple[np.ndarray, np.ndarray]:
    """Circular mean (n,) of rows of weights ``post`` (n, k) on ``grid`` within ``halfwidth`` (rad) of each row's
    largest weight (a front/back ambiguity's other mode does not drag it), and the whole row's spread (n,)."""
    peak = grid[np.argmax(post, axis=1)]
    near = np.abs(np.angle(np.exp(1j * (grid[None] - peak[:, None])))) <= halfwidth
    mean, _ = _circular(post * near, grid)
    _, spread = _circular(post, grid)
    return mean, spread


def seen(kp: np.ndarray, p: BodyParams) -> np.ndarray:
    """Which keypoints (n, 17) score at least ``min_score``."""
    return np.asarray(kp, dtype=float)[..., 2] >= p.min_score


SWAP = np.array([NOSE, R_EYE, L_EYE, R_EAR, L_EAR, R_SHOULDER, L_SHOULDER, R_HIP, L_HIP])  # RIGID, left <-> right


def _fit_cost(pred: np.ndarray, obs: np.ndarray, omega: np.ndarray, scale_std: float) -> np.ndarray:
    """-2 log likelihood (n, k) of observed points ``obs`` (n, m, 2) with weights ``omega`` (n, m; 1 / variance,
    0 unseen) against predicted ones ``pred`` (n, k, m, 2) after the best image shift and a scale near 1."""
    w = omega[:, None, :]  # (n, 1, m)
    wsum = np.maximum(omega.sum(axis=1), 1e-12)[:, None]
    px, py, ox, oy = pred[..., 0], pred[..., 1], obs[:, None, :, 0], obs[:, None, :, 1]
    dpx = px - (w * px).sum(-1, keepdims=True) / wsum[..., None]
    dpy = py - (w * py).sum(-1, keepdims=True) / wsum[..., None]
    dox = ox - (w * ox).sum(-1, keepdims=True) / wsum[..., None]
    doy = oy - (w * oy).sum(-1, keepdims=True) / wsum[..., None]
    spp = (w * (dpx * dpx + dpy * dpy)).sum(-1)
    spo = (w * (dpx * dox + dpy * doy)).sum(-1)
    soo = (w * (dox * dox + doy * doy)).sum(-1)
    prior = 1.0 / scale_std ** 2
    sc = (spo + prior) / (spp + prior)  # the scale minimising the sum plus (s - 1)^2 / scale_std^2
    return sc ** 2 * spp - 2 * sc * spo + soo + prior * (sc - 1) ** 2


def facing_costs(geom: object, kp: np.ndarray, xy: np.ndarray, grid: np.ndarray,
                 p: BodyParams) -> tuple[np.ndarray, np.ndarray]:
    """-2 log likelihood (n, k) of each yaw in ``grid`` (k,) for keypoints ``kp`` (n, 17, 3) (pixels, score) of
    people at ground points ``xy`` (n, 2), and how many template points each person showed (n,). The network
    swaps a person's left and right labels now and then (``swap_rate``): the likelihood mixes both labellings."""
    kp = np.asarray(kp, dtype=float).reshape(-1, 17, 3)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    idx = np.array(RIGID)
    pred, ppm = predict(geom, xy, grid, p)  # (n, k, m, 2), (n,)
    var = p.pixel_std ** 2 + (np.array(p.noise)[RIGID_GROUP][None] * ppm[:, None]) ** 2  # (n, m)
    w = seen(kp, p)
    obs = np.nan_to_num(kp[..., :2])
    costs = [_fit_cost(pred, obs[:, order], w[:, order] / var, p.scale_std) for order in (idx, SWAP)]
    lo = np.minimum(*costs)
    cost = lo - 2 * np.log((1 - p.swap_rate) * np.exp(-0.5 * (costs[0] - lo))
                           + p.swap_rate * np.exp(-0.5 * (costs[1] - lo)))
    # the face's points, seen or not, on people large enough for the network to tell
    big = ppm >= p.face_min_ppm
    if big.any():
        cam = np.asarray(geom.centre_m, dtype=float)[:2]  # type: ignore[attr-defined]
        to_cam = np.arctan2(cam[1] - xy[:, 1], cam[0] - xy[:, 0])
        off = np.abs(np.angle(np.exp(1j * (grid[None] - to_cam[:, None]))))  # (n, k)
        shown = off < math.radians(p.face_hidden_deg)
        found = kp[:, FACE, 2] >= p.face_score  # (n, 3)
        wrong = np.where(shown[:, :, None], ~found[:, None], found[:, None]).sum(axis=2)
        cost = cost + np.where(big[:, None], p.face_cost * wrong, 0.0)
    return cost, w[:, idx].sum(axis=1)


@dataclasses.dataclass
class KeypointFacing:
    """Per person (rows follow the keypoints): ground-frame yaw the chest faces (rad, atan2 in the camera's ground
    frame; NaN unknown), its spread (rad; inf unknown), and ``phi``, the same relative to the line of sight (0: the
    person looks at the camera, counter-clockwise positive, as ``facing.Facing.phi``)."""

    yaw: np.ndarray
    std: np.ndarray
    phi: np.ndarray


def _circular(post: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circular mean (n,) and spread sqrt(-2 ln R) (n,) of rows of weights ``post`` (n, k) on angles ``grid``."""
    z = (post * np.exp(1j * grid)[None]).sum(axis=1) / np.maximum(post.sum(axis=1), 1e-300)
    r = np.clip(np.abs(z), 1e-12, 1.0)
    return np.angle(z), np.sqrt(-2.0 * np.log(r))


def yaw_grid(p: BodyParams) -> np.ndarray:
    """The yaw hypotheses (k,) (rad, -pi to pi - step)."""
    return np.deg2rad(np.arange(-180.0, 180.0, p.step_deg))


def facing_posterior(geom: object, kp: np.ndarray, xy: np.ndarray,
                     p: BodyParams | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each person's posterior over ``yaw_grid`` (n, k) (rows sum to 1) from keypoints ``kp`` (n, 17, 3) (frame
    pixels x, y and score) of people standing at ground points ``xy`` (n, 2) (the camera's ground frame), and
    whether it says anything (n,): four template points seen or more, a shoulder or hip pair among them (others:
    uniform rows)."""
    p = p or BodyParams()
    kp = np.asarray(kp, dtype=float).reshape(-1, 17, 3)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    grid = yaw_grid(p)
    post = np.full((len(kp), len(grid)), 1.0 / len(grid))
    s = seen(kp, p)
    pair = (s[:, L_SHOULDER] & s[:, R_SHOULDER]) | (s[:, L_HIP] & s[:, R_HIP])
    ok = pair & (s[:, list(RIGID)].sum(axis=1) >= 4) & np.isfinite(xy).all(axis=1)
    if ok.any():
        cost, _ = facing_costs(geom, kp[ok], xy[ok], grid, p)
        q = np.exp(-0.5 * (cost - cost.min(axis=1, keepdims=True)))
        post[ok] = q / q.sum(axis=1, keepdims=True)
    return post, ok


def summarise_facing(post: np.ndarray, xy: np.ndarray, camera_xy: np.ndarray, p: BodyParams) -> KeypointFacing:
    """Posteriors over ``yaw_grid`` (n, k) -> circular mean, spread (plus ``floor_deg``) and ``phi`` relative to
    the line of sight from ``camera_xy`` (2,) to ``xy`` (n, 2); unknown where the spread exceeds
    ``max_std_deg`` (front and back alike, say)."""
    mean, spread = _circular(np.atleast_2d(post), yaw_grid(p))
    std = np.hypot(spread, math.radians(p.floor_deg))
    good = std <= math.radians(p.max_std_deg)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    to_cam = np.arctan2(camera_xy[1] - xy[:, 1], camera_xy[0] - xy[:, 0])
    return KeypointFacing(np.where(good, mean, np.nan), np.where(good, std, np.inf),
                          np.where(good, np.angle(np.exp(1j * (mean - to_cam))), np.nan))


def facing_from_keypoints(geom: object, kp: np.ndarray, xy: np.ndarray,
                          p: BodyParams | None = None) -> KeypointFacing:
    """The facing of people with keypoints ``kp`` (n, 17, 3) standing at ground points ``xy`` (n, 2), one frame
    (``facing_posterior`` summarised; a track's is ``FacingTrack``'s)."""
    p = p or BodyParams()
    post, ok = facing_posterior(geom, kp, xy, p)
    out = summarise_facing(post, xy, np.asarray(geom.centre_m, dtype=float)[:2], p)  # type: ignore[attr-defined]
    for a in (out.yaw, out.phi):
        a[~ok] = np.nan
    out.std[~ok] = np.inf
    return out


class FacingTrack:
    """One person's facing over time: a histogram filter on ``yaw_grid``. Between frames the facing turns at
    most by a wrapped Gaussian of ``turn_std`` rad/s; each frame's posterior (``facing_posterior``) multiplies in
    raised to a weight (a frame's keypoints are not independent of the last one's: the network sees the same
    person the same way for a while) and mixed with a uniform ``floor`` (a wrong frame cannot rule anything out).
    A multimodal frame (front or back) thus adds to whichever mode the track's other frames back."""

    def __init__(self, p: BodyParams, turn_std: float, floor: float = 0.0) -> None:
        self.p, self.turn_std, self.floor = p, turn_std, floor
        self.grid = yaw_grid(p)
        self.post = np.full(len(self.grid), 1.0 / len(self.grid))
        self.updates = 0

    def predict(self, dt: float) -> None:
        sigma = self.turn_std * math.sqrt(max(dt, 0.0))
        if sigma <= 0 or not self.updates:
            return
        d = np.angle(np.exp(1j * (self.grid - self.grid[0])))
        kernel = np.exp(-0.5 * (d / sigma) ** 2) if sigma > 1e-6 else (d == 0).astype(float)
        self.post = np.fft.irfft(np.fft.rfft(self.post) * np.fft.rfft(kernel / kernel.sum()), len(self.grid))
        self.post = np.maximum(self.post, 0.0)
        self.post /= self.post.sum()

    def update(self, post: np.ndarray, weight: float = 1.0) -> None:
        """Multiply in a posterior over the grid (k,), raised to ``weight``."""
        q = np.asarray(post, dtype=float)
        q = (q / q.max()) ** weight
        q = (1 - self.floor) * q / q.sum() + self.floor / len(q)
        self.post = self.post * q
        self.post /= self.post.sum()
        self.updates += 1

    def estimate(self) -> tuple[float, float]:
        """Yaw (rad) and std (rad); NaN and inf before any update or where the spread exceeds ``max_std_deg``."""
        if not self.updates:
            return math.nan, math.inf
        mean, spread = mode_mean(self.post[None], self.grid, math.radians(self.p.mode_halfwidth_deg))
        std = math.hypot(float(spread[0]), math.radians(self.p.floor_deg))
        return (float(mean[0]), std) if std <= math.radians(self.p.max_std_deg) else (math.nan, math.inf)
