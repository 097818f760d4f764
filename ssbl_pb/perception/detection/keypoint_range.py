"""A person's ground position from their keypoints when the feet are out of view (``ranging.range_boxes``'s
head cue for MoveNet, whose boxes start at the eyes, not the head top): pure geometry.

Along the line of sight through the body's middle column (``body_ray``), each candidate range (a log-spaced grid,
then a fine one around the best) places the template's head, shoulders and hips (``keypoints.BodyParams``) at
their heights for a stature fitted near the prior one (linearised, integrated out): the rows seen against those
predicted give the range and the stature together (the rows' spacing is the body's height in pixels, their place
its height above the floor), and the shoulders' width, where the facing is known, the range again (its apparent
width against its 0.32 m). The posterior over ranges gives the position and its variance along the line of sight;
across it, the column's noise.
"""

from __future__ import annotations

import numpy as np

from .keypoints import GROUPS, L_SHOULDER, R_SHOULDER, BodyParams, local_projection, project, seen, template

# share of a MoveNet box's height (eyes to ankles, about 1.5 m) the body reaches beyond its keypoints at the side: an
# arm and a shoulder's half-width, about 0.1 m. A box closer to the image's side is a cut body whose keypoints put it
# off by up to half a body (at the edge of the view, a member 40 deg off the axis was placed 0.6-0.9 m off, onto
# the neighbour's place, and the robot sidestepped into them)
BODY_MARGIN = 0.07
EYES_TO_ANKLES_M = 1.45  # m: the span of an adult's keypoints, eyes to ankles (stature 1.70 m): what a box's height
#   shows of a whole body, so ``BODY_MARGIN`` of it is 0.1 m at the person's range


def _part_rows(kp: np.ndarray, p: BodyParams) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per person and group (head, shoulders, hips): the mean row of its keypoints seen (n, 3; NaN none), the mean
    template height and forward offset of those (n, 3 each) and how many were seen (n, 3)."""
    body = template(p)
    s = seen(kp, p)
    rows, heights, ahead, counts = (np.full((len(kp), len(GROUPS)), np.nan) for _ in range(4))
    for g, idx in enumerate(GROUPS):
        w = s[:, idx].astype(float)
        cnt = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            rows[:, g] = (w * kp[:, idx, 1]).sum(axis=1) / cnt
            heights[:, g] = (w * body[idx, 2]).sum(axis=1) / cnt
            ahead[:, g] = (w * body[idx, 0]).sum(axis=1) / cnt
        counts[:, g] = cnt
    return rows, heights, ahead, counts


def vertical_rows(geom: object, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The image rows of a vertical line at ground points ``xy`` (..., 2) as a function of height z (m): the
    coefficients (a, b, c) of v(z) = (a z + b) / (c z + 1), a line's projection (exact for a pinhole; through
    heights 0, 1 and 2 m where the lens distorts), each (...,)."""
    xy = np.asarray(xy, dtype=float)
    pts = np.concatenate([np.broadcast_to(xy[..., None, :], xy.shape[:-1] + (3, 2)),
                          np.broadcast_to(np.array([[0.0], [1.0], [2.0]]), xy.shape[:-1] + (3, 1))], axis=-1)
    v = project(geom, pts)[..., 1]
    v0, v1, v2 = v[..., 0], v[..., 1], v[..., 2]
    c = (2 * v1 - v0 - v2) / (2 * (v2 - v1))
    return v1 * (c + 1) - v0, v0, c


def _range_costs(geom: object, ray: tuple[np.ndarray, np.ndarray], r: np.ndarray, rows: np.ndarray,
                 heights: np.ndarray, counts: np.ndarray, ahead: np.ndarray,
                 width: tuple[np.ndarray, np.ndarray, np.ndarray] | None, p: BodyParams,
                 scale: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """-2 log likelihood (n, R) of the ranges ``r`` (n, R) along the rays ``(origin (n, 2), unit (n, 2))``: each
    group's row (n, 3; NaN unseen) against the template's at a stature fitted near the prior (linearised), plus
    the shoulders' width (observed px, yaw, its std; per person, NaN unknown) where given; and the image's rows
    per metre of height 1 m up there (n, R). ``ahead`` (n, 3): each group's mean forward offset (m). ``scale``
    (n,): the px per metre the noise is taken at (the same at every range: no pull toward far ranges, whose
    smaller noise a noiseless fit would favour); None: each range's own."""
    origin, unit = ray
    # each group stands its template's forward offset (``ahead``, n x 3) along the facing from the body's axis:
    # nearer the camera by that times the cosine between the facing and the line of sight (unknown facing: 0)
    toward = np.zeros(len(r))
    if width is not None:
        yaw = width[1]
        toward = np.nan_to_num(-(np.cos(yaw) * unit[:, 0] + np.sin(yaw) * unit[:, 1]))
    rg = r[..., None] - np.nan_to_num(ahead)[:, None] * toward[:, None, None]  # (n, R, 3)
    xy = origin[:, None, None] + rg[..., None] * unit[:, None, None]  # (n, R, 3, 2)
    a, b, c = vertical_rows(geom, xy)  # (n, R, 3)
    h = np.nan_to_num(heights)[:, None]  # (n, 1, 3) template heights at ``p.stature``
    den = c * h + 1
    v = (a * h + b) / den
    dvdz = (a - b * c) / den ** 2
    slope = dvdz * h / p.stature  # rows per metre of stature
    ppm = np.abs(dvdz) if scale is None else scale[:, None, None]  # px per metre of height
    var = p.pixel_std ** 2 / np.maximum(counts, 1)[:, None] + (np.array(p.row_noise) * ppm) ** 2  # (n, R, 3)
    use = np.isfinite(rows)[:, None] & (counts[:, None] > 0)
    e = np.where(use, rows[:, None] - v, 0.0)  # residual at the prior stature
    k = np.where(use, slope, 0.0)
    # stature offset ds minimising sum (e - k ds)^2 / var + ds^2 / stature_std^2
    skk = (k * k / var).sum(-1) + 1.0 / p.stature_std ** 2
    ske = (k * e / var).sum(-1)
    cost = (e * e / var).sum(-1) - ske ** 2 / skk + np.where(use, np.log(var), 0.0).sum(-1) + np.log(skk)
    if width is not None:
        w_obs, yaw, yaw_std = width
        ok = np.isfinite(w_obs) & np.isfinite(yaw)
        if ok.any():
            _, half, sh_z = template(p)[L_SHOULDER]
            # the width at the first range (the shoulder line through the local projection), scaled to the others
            # by the magnification (px per metre of height at the shoulders)
            _, jac = local_projection(geom, xy[ok, 0, 1], np.array([sh_z]))
            left = 2 * half * np.stack([-np.sin(yaw[ok]), np.cos(yaw[ok])], axis=-1)
            w0 = np.hypot(*np.einsum("mij,mj->mi", jac[:, 0], left).T)
            a1, b1, c1 = a[ok][..., 1], b[ok][..., 1], c[ok][..., 1]
            mag = np.abs((a1 - b1 * c1) / (c1 * sh_z + 1) ** 2)  # (m, R)
            w_pred = w0[:, None] * mag / mag[:, :1]
            full = 2 * half * (mag if scale is None else scale[ok, None])  # the width changes with the yaw by
            #                                                                 up to its full width per radian
            var_w = (2 * p.pixel_std ** 2 + (p.width_rel_std * w_pred) ** 2
                     + (full * np.minimum(yaw_std[ok], 1.0)[:, None]) ** 2)
            cost[ok] += (w_obs[ok, None] - w_pred) ** 2 / var_w + np.log(var_w)
    return cost, np.abs((a - b * c) / (c + 1) ** 2)[..., 1]


def body_ray(geom: object, kp: np.ndarray, p: BodyParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The horizontal line of sight to each person (n,): the camera's ground point (n, 2), the unit direction
    (n, 2) through the group (head, shoulders, hips) seen whose height is farthest from the camera's (its ray
    meets that height in front of the camera whatever the person's stature), and whether any was seen (n,)."""
    rows, heights, _, counts = _part_rows(kp, p)
    cam = np.asarray(geom.centre_m, dtype=float)  # type: ignore[attr-defined]
    seen_any = np.isfinite(rows).any(axis=1)
    g = np.argmax(np.where(np.isfinite(rows), np.abs(np.nan_to_num(heights) - cam[2]), -1.0), axis=1)
    idx_all = seen(kp, p)
    u = np.full(len(kp), np.nan)
    for k, idx in enumerate(GROUPS):
        sel = g == k
        w = idx_all[sel][:, idx].astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            u[sel] = (w * kp[sel][:, idx, 0]).sum(axis=1) / w.sum(axis=1)
    n = len(kp)
    uv = np.column_stack([u, rows[np.arange(n), g]])
    unit = np.full((n, 2), np.nan)
    for k in range(len(GROUPS)):
        sel = seen_any & (g == k)
        if sel.any():
            a = geom.image_to_plane(uv[sel], float(np.mean(heights[sel, k])))  # type: ignore[attr-defined]
            d = a - cam[:2]
            unit[sel] = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    return np.broadcast_to(cam[:2], (n, 2)).copy(), unit, seen_any


RANGE_MIN, RANGE_MAX = 0.3, 120.0  # m: ranges searched (Pepper's nearest person to PETS' farthest, 60 m away)
COARSE, FINE = 96, 41  # grid sizes: log-spaced over the span, then linear over the posterior
COARSE_STEP = (RANGE_MAX / RANGE_MIN) ** (1 / (COARSE - 1))  # ratio of neighbours on the coarse grid (1.065)


def range_keypoints(geom: object, kp: np.ndarray, p: BodyParams | None = None, yaw: np.ndarray | None = None,
                    yaw_std: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ground positions (n, 2), covariances (n, 2, 2) and which were ranged (n,) of people from keypoints ``kp``
    (n, 17, 3): the head's, shoulders' and hips' rows (each seen group) fitted along the line of sight with the
    stature free around its prior, and the shoulders' width where the facing ``yaw`` (n,; rad, NaN unknown, with
    ``yaw_std``) is given. Needs two groups seen, or one and the shoulders' width."""
    p = p or BodyParams()
    kp = np.asarray(kp, dtype=float).reshape(-1, 17, 3)
    n = len(kp)
    xy, cov, ok = np.full((n, 2), np.nan), np.full((n, 2, 2), np.nan), np.zeros(n, dtype=bool)
    if n == 0:
        return xy, cov, ok
    rows, heights, ahead, counts = _part_rows(kp, p)
    origin, unit, _ = body_ray(geom, kp, p)
    s = seen(kp, p)
    w_obs = np.where(s[:, L_SHOULDER] & s[:, R_SHOULDER],
                     np.hypot(*(kp[:, L_SHOULDER, :2] - kp[:, R_SHOULDER, :2]).T), np.nan)
    yaw = np.full(n, np.nan) if yaw is None else np.asarray(yaw, dtype=float).reshape(n)
    yaw_std = np.full(n, np.inf) if yaw_std is None else np.asarray(yaw_std, dtype=float).reshape(n)
    groups = np.isfinite(rows).sum(axis=1)
    use = np.isfinite(unit).all(axis=1) & ((groups >= 2) | ((groups >= 1) & np.isfinite(w_obs) & np.isfinite(yaw)))
    if not use.any():
        return xy, cov, ok
    i = np.flatnonzero(use)
    width = (w_obs[i], yaw[i], yaw_std[i])
    ray = (origin[i], unit[i])
    coarse = np.broadcast_to(np.geomspace(RANGE_MIN, RANGE_MAX, COARSE), (len(i), COARSE))
    c0, mag0 = _range_costs(geom, ray, coarse, rows[i], heights[i], counts[i], ahead[i], width, p)
    p0 = np.exp(-0.5 * (c0 - c0.min(axis=1, keepdims=True)))
    p0 /= p0.sum(axis=1, keepdims=True)
    mean0 = (p0 * coarse).sum(axis=1)
    sd0 = np.sqrt((p0 * (coarse - mean0[:, None]) ** 2).sum(axis=1))
    best = coarse[0, np.argmin(c0, axis=1)]
    # the fine grid spans the coarse posterior (4 of its spreads and a coarse step beyond its peak and its mean)
    reach = 4 * sd0 + best * (COARSE_STEP - 1)
    lo = np.maximum(np.minimum(best, mean0) - reach, RANGE_MIN)
    hi = np.maximum(best, mean0) + reach
    fine = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, FINE)[None]
    scale = (p0 * mag0).sum(axis=1)
    c1, mag = _range_costs(geom, ray, fine, rows[i], heights[i], counts[i], ahead[i], width, p, scale)
    post = np.exp(-0.5 * (c1 - c1.min(axis=1, keepdims=True)))
    post /= post.sum(axis=1, keepdims=True)
    r = fine[np.arange(len(i)), np.argmax(post, axis=1)]  # the mode: the stature's ridge skews the mean far
    step = (hi - lo) / (FINE - 1)
    var_r = (post * (fine - r[:, None]) ** 2).sum(axis=1) + step ** 2 / 12  # about the mode; the grid's step
    u = unit[i]
    xy[i] = origin[i] + r[:, None] * u
    ppm = (post * mag).sum(axis=1)
    var_lat = (p.pixel_std ** 2 + (p.noise[1] * ppm) ** 2) / ppm ** 2  # the column's noise, across the ray
    along = u[:, :, None] * u[:, None, :]
    cov[i] = var_r[:, None, None] * along + var_lat[:, None, None] * (np.eye(2)[None] - along)
    ok[i] = True
    return xy, cov, ok
