"""Base dynamics identification: per axis, command latency, first-order time constant, acceleration and speed
limits, fitted by scipy least squares to a log (``dynamics_log``).

The per-axis model is ``HolonomicBase`` restricted to one axis: the command is clipped to ``vmax``, delayed by
``latency``, followed through a first-order lag ``tau`` and reached at most at ``amax``. It is simulated on a
grid of at most 20 ms; the delayed command is averaged over each grid step, which makes the cost continuous
in the latency (a plain sample shift would make it a staircase that least squares cannot follow).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import least_squares

from ..cli import progress as bar
from ..params import CalibrationError, RobotParams
from .dynamics_log import AXES, DynamicsLog

NAMES = ("latency_s", "time_constant_s", "max_accel", "max_speed")
LOWER = np.array([0.0, 0.0, 0.01, 0.01])
UPPER = np.array([1.0, 3.0, 20.0, 5.0])


def simulate_axis(t: np.ndarray, cmd: np.ndarray, theta: np.ndarray, v0: float = 0.0, max_dt: float = 0.005,
                  window_mean: bool = False, stats: dict | None = None) -> np.ndarray:
    """Model velocity at the log times ``t`` for ``theta`` = (latency, tau, amax, vmax).

    ``cmd[i]`` is held over [t_i, t_{i+1}). With ``window_mean`` the result is the mean velocity over
    [t_{i-1}, t_{i+1}], as a central difference of odometry poses measures it. ``stats``, when given, receives
    ``accel_limited``: the share of grid steps where the acceleration limit was active.
    """
    lat, tau, amax, vmax = (float(v) for v in theta)
    dt_log = float(np.median(np.diff(t)))
    m = max(1, math.ceil(dt_log / max_dt - 1e-9))
    h = dt_log / m
    grid = np.arange(t[0], t[-1] + 0.5 * h, h)
    c = np.clip(cmd, -vmax, vmax)
    # integral of the zero-order-held (clipped) command, evaluated at the delayed grid edges
    knots = np.concatenate([t, [t[-1] + dt_log]])
    cum = np.concatenate([[0.0], np.cumsum(c * np.diff(knots))])
    a = grid - lat
    area = np.interp(a + h, knots, cum) - np.interp(a, knots, cum)
    area[a + h <= knots[0]] = 0.0
    target = area / h
    k = 1.0 if tau < 1e-6 else 1.0 - math.exp(-h / tau)
    step = amax * h
    v = float(v0)
    vel = np.empty(len(grid))
    limited = 0
    for i, u in enumerate(target.tolist()):
        vel[i] = v  # velocity at the start of step i
        dv = (u - v) * k
        if dv > step:
            dv = step
            limited += 1
        elif dv < -step:
            dv = -step
            limited += 1
        v += dv
    if stats is not None:
        stats["accel_limited"] = limited / max(1, len(grid))
    if not window_mean:
        return np.interp(t, grid, vel)
    pos = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * h)])
    n = len(t)
    i0, i1 = np.clip(np.arange(n) - 1, 0, n - 1), np.clip(np.arange(n) + 1, 0, n - 1)
    return (np.interp(t[i1], grid, pos) - np.interp(t[i0], grid, pos)) / (t[i1] - t[i0])


@dataclasses.dataclass
class AxisFit:
    """One axis: fitted (latency, tau, amax, vmax), their 1-sigma, the residual RMS and what was identified."""

    axis: str
    theta: np.ndarray
    std: np.ndarray
    rms: float
    identified: dict[str, bool]  # vmax: commanded beyond it; amax: accel-limited phases seen
    window: tuple[int, int]  # rows used
    success: bool

    def as_dict(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(NAMES, self.theta, strict=True)}


def _window(log: DynamicsLog, j: int, tail_s: float = 2.0) -> tuple[int, int]:
    active = np.flatnonzero(np.abs(log.cmd[:, j]) > 1e-9)
    if active.size == 0:
        raise CalibrationError(f"{log.path}: axis {AXES[j]} is never commanded")
    lo = max(0, int(active[0]) - 5)
    hi = min(len(log.t), int(active[-1]) + int(tail_s / log.dt) + 1)
    return lo, hi


def fit_axis(log: DynamicsLog, axis: str, starts: tuple[float, ...] = (0.05, 0.3)) -> AxisFit:
    """Least-squares fit of one axis over the rows where it is commanded (plus a 2 s tail)."""
    j = AXES.index(axis)
    lo, hi = _window(log, j)
    t, cmd, meas = log.t[lo:hi], log.cmd[lo:hi, j], log.vel[lo:hi, j]
    vpeak = float(np.percentile(np.abs(meas), 99.5))
    cmax = float(np.abs(cmd).max())
    v0 = float(np.clip(min(vpeak * 1.02, cmax), LOWER[3], UPPER[3]))
    # accel starts: reaching the peak speed in 1 s and in 0.3 s. Start low: while the limit binds the cost
    # has a gradient in it; from a limit that never binds (e.g. one estimated from noisy differences) the
    # fit trades latency and lag for it instead
    a_starts = (v0 / 1.0, v0 / 0.3)

    def resid(x: np.ndarray) -> np.ndarray:
        return simulate_axis(t, cmd, x, meas[0] if not log.from_pose else 0.0, window_mean=log.from_pose) - meas

    runs = []
    for lat0 in starts:  # multi-start: latency and the accel limit trade off against the lag
        for a0 in a_starts:
            x0 = np.clip(np.array([lat0, 0.2, a0, v0]), LOWER + 1e-6, UPPER - 1e-6)
            runs.append(least_squares(resid, x0, bounds=(LOWER, UPPER), x_scale=np.array([0.05, 0.1, 0.1, 0.1]),
                                      diff_step=1e-3, max_nfev=200))
    best = min(runs, key=lambda r: r.cost)
    # while the accel limit binds, a sub-step latency shift changes nothing, so the latency gradient can be
    # zero and the solver stalls: scan latency around the solution (others fixed) and refit from the best
    x = best.x.copy()
    grid = x[0] + np.arange(-12, 13) * 0.0025
    grid = grid[(grid >= LOWER[0]) & (grid <= UPPER[0])]
    costs = [float(np.sum(resid(np.r_[lat, x[1:]]) ** 2)) for lat in grid]
    if min(costs) < 2.0 * best.cost - 1e-12:
        x[0] = grid[int(np.argmin(costs))]
        r = least_squares(resid, np.clip(x, LOWER + 1e-6, UPPER - 1e-6), bounds=(LOWER, UPPER),
                          x_scale=np.array([0.05, 0.1, 0.1, 0.1]), diff_step=1e-3, max_nfev=200)
        if r.cost < best.cost:
            best = r
    dof = max(1, len(t) - 4)
    s2 = 2.0 * best.cost / dof
    try:
        cov = np.linalg.pinv(best.jac.T @ best.jac) * s2
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(4, np.nan)
    theta = best.x
    stats: dict = {}
    simulate_axis(t, cmd, theta, stats=stats)
    identified = {"max_speed": bool(cmax > theta[3] * 1.05), "max_accel": stats["accel_limited"] > 0.01}
    return AxisFit(axis, theta, std, float(math.sqrt(s2)), identified, (lo, hi), bool(best.success))


@dataclasses.dataclass
class DynamicsResult:
    """Per-axis fits and the ``RobotParams`` fields they give (latency and lag: median over axes)."""

    fits: dict[str, AxisFit]
    params: dict[str, float]
    notes: list[str]


def _combine(vals: list[float], stds: list[float], floor: float) -> float:
    """Median of three or more axis estimates (robust to one stalled fit), else an inverse-variance mean
    with each sigma floored at ``floor`` (a zero sigma means a flat cost, not certainty)."""
    if len(vals) >= 3:
        return float(np.median(vals))
    w = np.array([1.0 / max(s, floor) ** 2 if np.isfinite(s) else 0.0 for s in stds]) + 1e-12
    return float(np.sum(w * np.array(vals)) / np.sum(w))


def identify(log: DynamicsLog, axes: tuple[str, ...] = AXES, base: RobotParams | None = None,
             progress: bool = False) -> DynamicsResult:
    """Fit each commanded axis; combine into RobotParams fields (shared latency and lag: median of the axes)."""
    base = base or RobotParams()
    fits = {}
    notes = []
    if not any(np.abs(log.cmd[:, AXES.index(ax)]).max() > 1e-9 for ax in axes):  # before any progress line
        raise CalibrationError(f"{log.path}: no axis is ever commanded")
    it = axes
    if progress:
        it = bar(axes, "fitting axes", "axis")
    for ax in it:
        j = AXES.index(ax)
        if np.abs(log.cmd[:, j]).max() <= 1e-9:
            notes.append(f"axis {ax} never commanded: its limits keep their defaults")
            continue
        fits[ax] = fit_axis(log, ax)
    if not fits:
        raise CalibrationError(f"{log.path}: no axis is ever commanded")
    params: dict[str, float] = {}
    params["latency_s"] = _combine([f.theta[0] for f in fits.values()], [f.std[0] for f in fits.values()], 0.005)
    params["time_constant_s"] = _combine([f.theta[1] for f in fits.values()], [f.std[1] for f in fits.values()],
                                         0.005)
    lin = [fits[a] for a in ("vx", "vy") if a in fits]
    for field, idx, group, label in (("max_speed", 3, lin, "max_speed"), ("max_accel", 2, lin, "max_accel")):
        ok = [f for f in group if f.identified[label]]
        if ok:
            params[field] = _combine([f.theta[idx] for f in ok], [f.std[idx] for f in ok], 0.005)
        elif group:
            notes.append(f"{field} not identified (commands never exceeded it / no accel-limited phase): "
                         f"kept {getattr(base, field)}")
    if "wz" in fits:
        f = fits["wz"]
        for field, idx, label in (("max_yaw_rate", 3, "max_speed"), ("max_yaw_accel", 2, "max_accel")):
            if f.identified[label]:
                params[field] = float(f.theta[idx])
            else:
                notes.append(f"{field} not identified: kept {getattr(base, field)}")
    if params.get("max_speed", 0.0) > 0.55:
        notes.append(f"max_speed {params['max_speed']:.3f} > Pepper's 0.55 m/s hardware max: clipped to 0.55")
        params["max_speed"] = 0.55
    return DynamicsResult(fits, {k: round(v, 4) for k, v in params.items()}, notes)
