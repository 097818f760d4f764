"""Compiled (numba) kernels of the batched env: one call steps, observes or shields every copy.

Each kernel loops over the copies and runs, per copy, the same scalar arithmetic as the single env's Python code
(``base.HolonomicBase.step``, ``humans.Group.step`` with ``forces`` eqs. 8-10, ``humans.widest_gap``,
``ApproachGroupEnv.step`` with ``reward`` eqs. 11-15, ``observation.vector_observation`` and
``shield.shield_action``): numpy's fixed cost per call on arrays of 2-6 agents made an array-operation version
cost ~500 us per step of 8 copies, these ~35 us (shield and smoothing included). ``tests/test_batched.py``
holds them to the single env step for step; change both together. Parameters travel as one float array packed
by ``pack_params`` (indices below). Compiled on first use and cached next to this file (``cache=True``), so
later processes start at once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..params import RobotParams, SocialParams, WorldParams
from .observation import MAX_MEMBERS, MEMBER_FIELDS, OBS_LIMIT, POS_SCALE
from .reward import BRAKE_GAIN, BRAKE_RADIUS, TERMS
from .task import TaskParams

TWO_PI = 2.0 * math.pi
EPS = 1e-9
N_TERMS = len(TERMS)
# indices into the packed parameter array
(MAX_SPEED, MAX_YAW_RATE, MAX_ACCEL, MAX_YAW_ACCEL, TIME_CONSTANT, HALF_LENGTH, HALF_WIDTH, DELAY_FRAC, D_P, D_S,
 D_PUB, W_COH, W_EQ, W_REP, NEWTON_PER_DRAG, DRAG, SATURATION, DEADBAND, HUMAN_RADIUS, MEMBER_MAX_SPEED, TURN_RATE,
 JOIN_MARGIN, DT, HEADING_GAIN, SLOT_TOL, STOP_SPEED, HEADING_TOL, INTIMATE, BAND, MAX_STEPS, KEEP_OUT_EXTRA, ROOM_X,
 ROOM_Y, TURN, DELAY_STEPS, N_PARAMS) = range(36)


def pack_params(world: WorldParams, robot: RobotParams, social: SocialParams, task: TaskParams) -> np.ndarray:
    """The parameters the kernels read, as one float array (indices: the constants of this module)."""
    delay = round(robot.latency_s / world.dt, 9)
    p = np.zeros(N_PARAMS)
    values = {
        MAX_SPEED: robot.max_speed, MAX_YAW_RATE: robot.max_yaw_rate, MAX_ACCEL: robot.max_accel,
        MAX_YAW_ACCEL: robot.max_yaw_accel, TIME_CONSTANT: robot.time_constant_s, HALF_LENGTH: robot.length / 2,
        HALF_WIDTH: robot.width / 2, DELAY_FRAC: delay - int(delay), DELAY_STEPS: int(delay),
        D_P: social.personal_radius, D_S: social.social_radius, D_PUB: social.public_radius,
        W_COH: social.weight_cohesion, W_EQ: social.weight_equality, W_REP: social.weight_repulsion,
        NEWTON_PER_DRAG: social.force_newton / social.mass / social.drag, DRAG: social.drag,
        SATURATION: social.saturation, DEADBAND: social.equality_deadband, HUMAN_RADIUS: social.human_radius,
        MEMBER_MAX_SPEED: social.max_speed, TURN_RATE: social.max_turn_rate, JOIN_MARGIN: social.join_margin,
        DT: world.dt, HEADING_GAIN: task.heading_gain, SLOT_TOL: task.slot_tolerance, STOP_SPEED: task.stop_speed,
        HEADING_TOL: math.radians(task.heading_tolerance_deg), INTIMATE: task.intimate_zone,
        BAND: task.proximity_band, MAX_STEPS: task.max_steps,
        KEEP_OUT_EXTRA: social.human_radius + robot.reach + task.intimate_zone + task.route_margin,
        ROOM_X: world.room_size[0], ROOM_Y: world.room_size[1], TURN: float(task.turn),
    }
    for k, v in values.items():
        p[k] = v
    return p


@njit(cache=True)
def _remainder(x: float) -> float:
    """``math.remainder(x, 2 pi)``."""
    return x - TWO_PI * np.rint(x / TWO_PI)


@njit(cache=True)
def _clip(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@njit(cache=True)
def _heading_error(pose: np.ndarray, centre: np.ndarray, i: int) -> float:
    return _remainder(math.atan2(centre[i, 1] - pose[i, 1], centre[i, 0] - pose[i, 0]) - pose[i, 2])


# -- the base ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _base_step(p: np.ndarray, pose: np.ndarray, vel: np.ndarray, queue: np.ndarray, i: int, fx: float, fy: float,
               w: float) -> None:
    """``HolonomicBase.step`` for copy ``i`` (command already in the body frame)."""
    n = math.hypot(fx, fy)
    if n > p[MAX_SPEED]:
        fx, fy = fx * p[MAX_SPEED] / n, fy * p[MAX_SPEED] / n
    w = _clip(w, -p[MAX_YAW_RATE], p[MAX_YAW_RATE])
    k, f = int(p[DELAY_STEPS]), p[DELAY_FRAC]
    if k > 0 or f != 0.0:
        for j in range(queue.shape[1] - 1, 0, -1):
            queue[i, j] = queue[i, j - 1]
        queue[i, 0, 0], queue[i, 0, 1], queue[i, 0, 2] = fx, fy, w
        if f == 0.0:
            fx, fy, w = queue[i, k, 0], queue[i, k, 1], queue[i, k, 2]
        else:
            fx = (1.0 - f) * queue[i, k, 0] + f * queue[i, k + 1, 0]
            fy = (1.0 - f) * queue[i, k, 1] + f * queue[i, k + 1, 1]
            w = (1.0 - f) * queue[i, k, 2] + f * queue[i, k + 1, 2]
    x, y, yaw = pose[i, 0], pose[i, 1], pose[i, 2]
    vx, vy, wz = vel[i, 0], vel[i, 1], vel[i, 2]
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty, tw = c * fx - s * fy, s * fx + c * fy, w
    dt = p[DT]
    if p[TIME_CONSTANT] > 0:
        kk = 1.0 - math.exp(-dt / p[TIME_CONSTANT])
        tx, ty, tw = vx + (tx - vx) * kk, vy + (ty - vy) * kk, wz + (tw - wz) * kk
    dvx, dvy = tx - vx, ty - vy
    n = math.hypot(dvx, dvy)
    amax = p[MAX_ACCEL] * dt
    if n > amax:
        dvx, dvy = dvx * amax / n, dvy * amax / n
    wmax = p[MAX_YAW_ACCEL] * dt
    dw = _clip(tw - wz, -wmax, wmax)
    nvx, nvy, nwz = vx + dvx, vy + dvy, wz + dw
    pose[i, 0] = x + 0.5 * (vx + nvx) * dt
    pose[i, 1] = y + 0.5 * (vy + nvy) * dt
    pose[i, 2] = _remainder(yaw + 0.5 * (wz + nwz) * dt)
    vel[i, 0], vel[i, 1], vel[i, 2] = nvx, nvy, nwz


# -- the members ------------------------------------------------------------------------------------------
@njit(cache=True)
def _group_step(p: np.ndarray, i: int, rx: float, ry: float, count: np.ndarray, pos: np.ndarray, mvel: np.ndarray,
                myaw: np.ndarray, centre0: np.ndarray, base_r: np.ndarray, joined_r: np.ndarray, join_r: np.ndarray,
                ring_off: np.ndarray, comfort: np.ndarray, shift_k: np.ndarray, centre: np.ndarray,
                radius: np.ndarray, join_w: np.ndarray, force: np.ndarray, rep: np.ndarray,
                robot_force: np.ndarray) -> None:
    """``Group.step`` for copy ``i`` with the robot at (rx, ry): SFFM forces (eqs. 8-10) on every agent, the
    members' motion under them, the robot's field for the rewards."""
    n = count[i]
    k = n + 1
    # update_centre
    dx, dy = rx - centre0[i, 0], ry - centre0[i, 1]
    d = math.hypot(dx, dy)
    w = min(1.0, max(0.0, (join_r[i] + p[JOIN_MARGIN] - d) / p[JOIN_MARGIN]))
    join_w[i] = w
    shift = w * shift_k[i] / (n + 1)
    cx, cy = centre0[i, 0] + shift * dx, centre0[i, 1] + shift * dy
    centre[i, 0], centre[i, 1] = cx, cy
    R = base_r[i] + w * (joined_r[i] - base_r[i])
    radius[i] = R
    joined = w >= 0.5
    px = np.empty(k)
    py = np.empty(k)
    for a in range(n):
        px[a], py[a] = pos[i, a, 0], pos[i, a, 1]
    px[n], py[n] = rx, ry
    fcx, fcy, fex, fey, frx, fry = np.zeros(k), np.zeros(k), np.zeros(k), np.zeros(k), np.zeros(k), np.zeros(k)
    d_p, d_s, d_pub = p[D_P], p[D_S], p[D_PUB]
    for a in range(k):
        # neighbours: any other agent for repulsion (members keep their comfort distance from each other, the
        # personal zone from the robot); for equality and cohesion the robot only once it has joined
        r_cnt, r_sx, r_sy, depth = 0.0, 0.0, 0.0, 0.0
        s_cnt, s_sx, s_sy, a_cnt = 0.0, 0.0, 0.0, 0.0
        for b in range(k):
            if b == a:
                continue
            dist = math.hypot(px[b] - px[a], py[b] - py[a])
            zone = comfort[i, a] if a < n and b < n else d_p
            if dist < zone:
                r_cnt += 1.0
                r_sx += px[b]
                r_sy += py[b]
                depth = max(depth, zone - dist)
            if b == n and not joined:
                continue
            if dist < d_s:
                s_cnt += 1.0
                s_sx += px[b]
                s_sy += py[b]
            if dist < d_pub:
                a_cnt += 1.0
        # eq. 8 repulsion
        prx, pry = r_sx - r_cnt * px[a], r_sy - r_cnt * py[a]
        nr = math.hypot(prx, pry)
        if nr > EPS:
            mag = -(depth ** 2)
            frx[a], fry[a] = mag * (prx / nr), mag * (pry / nr)
        # eq. 9 equality
        c1 = s_cnt + 1.0
        ecx, ecy = (px[a] + s_sx) / c1, (py[a] + s_sy) / c1
        self_d = math.hypot(ecx - px[a], ecy - py[a])
        tot = 0.0
        for b in range(k):
            if b == a or (b == n and not joined):
                continue
            if math.hypot(px[b] - px[a], py[b] - py[a]) < d_s:
                tot += math.hypot(ecx - px[b], ecy - py[b])
        if self_d > EPS:
            sc = 1.0 - ((self_d + tot) / c1) / self_d
            fex[a], fey[a] = sc * (ecx - px[a]), sc * (ecy - py[a])
        # eq. 10 cohesion
        ox, oy = cx - px[a], cy - py[a]
        do = math.hypot(ox, oy)
        if do > EPS:
            sc = (a_cnt / c1) * (1.0 - (R + ring_off[i, a] if a < n else R) / do)
            fcx[a], fcy[a] = sc * ox, sc * oy
    robot_force[i, 0] = fcx[n] + fex[n] + frx[n]
    robot_force[i, 1] = fcy[n] + fey[n] + fry[n]
    decay = math.exp(-p[DRAG] * p[DT])
    dt, sat, db = p[DT], p[SATURATION], p[DEADBAND]
    for a in range(n):
        ring = abs(math.hypot(px[a] - cx, py[a] - cy) - (R + ring_off[i, a]))
        gate = min(max((ring - db) / db, 0.0), 1.0)
        sc = max(math.hypot(fcx[a], fcy[a]), sat)
        se = max(math.hypot(fex[a], fey[a]), sat)
        sr = max(math.hypot(frx[a], fry[a]), sat)
        tx = p[W_COH] * (fcx[a] / sc) + (p[W_EQ] * gate) * (fex[a] / se) + p[W_REP] * (frx[a] / sr)
        ty = p[W_COH] * (fcy[a] / sc) + (p[W_EQ] * gate) * (fey[a] / se) + p[W_REP] * (fry[a] / sr)
        force[i, a, 0], force[i, a, 1] = fcx[a] + gate * fex[a] + frx[a], fcy[a] + gate * fey[a] + fry[a]
        rep[i, a, 0], rep[i, a, 1] = frx[a], fry[a]
        st = max(math.hypot(tx, ty), 1.0)
        vix, viy = tx / st * p[NEWTON_PER_DRAG], ty / st * p[NEWTON_PER_DRAG]
        v0x, v0y = mvel[i, a, 0], mvel[i, a, 1]
        vx, vy = vix + (v0x - vix) * decay, viy + (v0y - viy) * decay
        speed = math.hypot(vx, vy)
        if speed > p[MEMBER_MAX_SPEED]:
            vx, vy = vx * (p[MEMBER_MAX_SPEED] / speed), vy * (p[MEMBER_MAX_SPEED] / speed)
        mvel[i, a, 0], mvel[i, a, 1] = vx, vy
        pos[i, a, 0] = px[a] + (0.5 * dt) * (v0x + vx)
        pos[i, a, 1] = py[a] + (0.5 * dt) * (v0y + vy)
        # turn toward the conversation centre at a bounded rate (Python's % is numpy's remainder)
        tox, toy = cx - pos[i, a, 0], cy - pos[i, a, 1]
        err = (math.atan2(toy, tox) - myaw[i, a] + math.pi) % TWO_PI - math.pi
        lim = p[TURN_RATE] * dt
        turn = _clip(err, -lim, lim) if math.hypot(tox, toy) > 1e-9 else 0.0
        myaw[i, a] = (myaw[i, a] + turn) % TWO_PI


@njit(cache=True)
def _free_slot(i: int, rx: float, ry: float, count: np.ndarray, pos: np.ndarray, centre: np.ndarray,
               radius: np.ndarray, slot: np.ndarray, keep: float) -> None:
    """``Group.free_slot`` (``humans.widest_gap`` with the robot's side breaking ties within 10 deg, then
    ``humans.slot_distance``)."""
    n = count[i]
    cx, cy = centre[i, 0], centre[i, 1]
    toward = math.atan2(ry - cy, rx - cx)
    a = np.empty(n)
    for j in range(n):
        v = math.atan2(pos[i, j, 1] - cy, pos[i, j, 0] - cx) % TWO_PI
        m = j
        while m > 0 and a[m - 1] > v:  # insertion sort (n <= 5)
            a[m] = a[m - 1]
            m -= 1
        a[m] = v
    gaps = np.empty(n)
    for j in range(n - 1):
        gaps[j] = a[j + 1] - a[j]
    gaps[n - 1] = a[0] + TWO_PI - a[n - 1]
    tie = gaps.max() - math.radians(10.0)
    pick, pick_err = -1, np.inf
    for j in range(n):
        if gaps[j] < tie:
            continue
        err = abs(_remainder(a[j] + gaps[j] / 2.0 - toward))
        if err < pick_err:
            pick, pick_err = j, err
    mid = (a[pick] + gaps[pick] / 2.0) % TWO_PI
    ux, uy = math.cos(mid), math.sin(mid)
    t = radius[i]
    if keep > 0.0:
        for _ in range(n):
            moved = False
            for j in range(n):
                qx, qy = pos[i, j, 0] - cx, pos[i, j, 1] - cy
                b = qx * ux + qy * uy
                h2 = qx * qx + qy * qy - b * b
                if (t - b) * (t - b) + h2 < keep * keep:
                    t = b + math.sqrt(max(keep * keep - h2, 0.0))
                    moved = True
            if not moved:
                break
    slot[i, 0], slot[i, 1] = cx + t * ux, cy + t * uy


# -- the task ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _clearance(p: np.ndarray, pose: np.ndarray, i: int, hx: float, hy: float) -> float:
    """``World.human_clearance`` for one member at (hx, hy)."""
    c, s = math.cos(pose[i, 2]), math.sin(pose[i, 2])
    dx, dy = hx - pose[i, 0], hy - pose[i, 1]
    lx, ly = dx * c + dy * s, -dx * s + dy * c
    ox, oy = max(abs(lx) - p[HALF_LENGTH], 0.0), max(abs(ly) - p[HALF_WIDTH], 0.0)
    return math.hypot(ox, oy) - p[HUMAN_RADIUS]


@njit(cache=True)
def _route(x: float, y: float, sx: float, sy: float, cx: float, cy: float, keep_out: float) -> float:
    """``reward.route_distance``."""
    rx, ry, qx, qy = x - cx, y - cy, sx - cx, sy - cy
    r, rq = math.hypot(rx, ry), math.hypot(qx, qy)
    dth = abs(_remainder(math.atan2(ry, rx) - math.atan2(qy, qx)))
    R = max(keep_out, rq)
    if r < R:
        return math.hypot(rx - qx, ry - qy) + R * dth
    beta = math.acos(R / r)
    if dth <= beta:
        to_rim = math.sqrt(max(r * r + R * R - 2.0 * r * R * math.cos(dth), 0.0))
    else:
        to_rim = math.sqrt(r * r - R * R) + R * (dth - beta)
    return to_rim + (R - rq)


@njit(cache=True)
def _potential(distance: float, speed: float) -> float:
    """``reward.slot_potential`` with its defaults."""
    return -(distance + BRAKE_GAIN * speed * max(0.0, 1.0 - distance / BRAKE_RADIUS))


@njit(cache=True)
def potentials(p: np.ndarray, pose: np.ndarray, slot: np.ndarray, centre: np.ndarray, radius: np.ndarray,
               speed: np.ndarray, out: np.ndarray) -> None:
    """``slot_potential(route_distance(...), speed)`` of every copy."""
    for i in range(pose.shape[0]):
        d = _route(pose[i, 0], pose[i, 1], slot[i, 0], slot[i, 1], centre[i, 0], centre[i, 1],
                   radius[i] + p[KEEP_OUT_EXTRA])
        out[i] = _potential(d, speed[i])


@njit(cache=True)
def step(p: np.ndarray, weights: np.ndarray, actions: np.ndarray, pose: np.ndarray, vel: np.ndarray,
         queue: np.ndarray, count: np.ndarray, pos: np.ndarray, mvel: np.ndarray, myaw: np.ndarray,
         centre0: np.ndarray, base_r: np.ndarray, joined_r: np.ndarray, join_r: np.ndarray, ring_off: np.ndarray,
         comfort: np.ndarray, keep: np.ndarray, shift_k: np.ndarray, centre: np.ndarray, radius: np.ndarray,
         join_w: np.ndarray, force: np.ndarray, rep: np.ndarray, robot_force: np.ndarray, steps: np.ndarray,
         prev_accel: np.ndarray, clearance: np.ndarray, slot: np.ndarray, potential: np.ndarray, sums: np.ndarray,
         rewards: np.ndarray, flags: np.ndarray) -> None:
    """``ApproachGroupEnv.step`` for every copy; ``flags[i]`` = (terminated, truncated, success, violation,
    collision). Arrays are the batch's state, updated in place."""
    dt, ms = p[DT], p[MAX_SPEED]
    mb = np.empty((pos.shape[1], 2))
    for i in range(pose.shape[0]):
        a0, a1 = _clip(actions[i, 0], -1.0, 1.0), _clip(actions[i, 1], -1.0, 1.0)
        if p[TURN] > 0:
            fx, fy, w = a0 * ms, a1 * ms, _clip(actions[i, 2], -1.0, 1.0) * p[MAX_YAW_RATE]
        else:  # the approach frame turned into the body frame; the base turns toward the centre
            e = _heading_error(pose, centre, i)
            w = _clip(p[HEADING_GAIN] * e, -p[MAX_YAW_RATE], p[MAX_YAW_RATE])
            c, s = math.cos(e), math.sin(e)
            fx, fy = (c * a0 - s * a1) * ms, (s * a0 + c * a1) * ms
        bx, by, bvx, bvy = pose[i, 0], pose[i, 1], vel[i, 0], vel[i, 1]
        n = count[i]
        for j in range(n):
            mb[j, 0], mb[j, 1] = pos[i, j, 0], pos[i, j, 1]
        potential_before = potential[i]
        _base_step(p, pose, vel, queue, i, fx, fy, w)
        x, y = pose[i, 0], pose[i, 1]
        _group_step(p, i, x, y, count, pos, mvel, myaw, centre0, base_r, joined_r, join_r, ring_off, comfort,
                    shift_k, centre, radius, join_w, force, rep, robot_force)
        steps[i] += 1
        _free_slot(i, x, y, count, pos, centre, radius, slot, keep[i])
        slot_after = math.hypot(slot[i, 0] - x, slot[i, 1] - y)
        nearest, prox = np.inf, 0.0
        for j in range(n):
            cl = _clearance(p, pose, i, pos[i, j, 0], pos[i, j, 1])
            nearest = min(nearest, cl)
            closed = max(clearance[i, j] - cl, 0.0)
            prox += closed * min(max((p[INTIMATE] + p[BAND] - cl) * (1.0 / p[BAND]), 0.0), 1.0)
            clearance[i, j] = cl
        hc, hs = abs(math.cos(pose[i, 2])), abs(math.sin(pose[i, 2]))
        ex, ey = p[HALF_LENGTH] * hc + p[HALF_WIDTH] * hs, p[HALF_LENGTH] * hs + p[HALF_WIDTH] * hc
        rxh, ryh = p[ROOM_X] / 2, p[ROOM_Y] / 2
        wall = rxh - x - ex <= 0.0 or x - ex + rxh <= 0.0 or ryh - y - ey <= 0.0 or y - ey + ryh <= 0.0
        collided = nearest <= 0.0 or wall
        violation = collided or nearest < p[INTIMATE]
        speed = math.hypot(vel[i, 0], vel[i, 1])
        success = (not violation and slot_after < p[SLOT_TOL] and speed < p[STOP_SPEED]
                   and abs(_heading_error(pose, centre, i)) < p[HEADING_TOL])
        ax, ay = (vel[i, 0] - bvx) / dt, (vel[i, 1] - bvy) / dt
        d = _route(x, y, slot[i, 0], slot[i, 1], centre[i, 0], centre[i, 1], radius[i] + p[KEEP_OUT_EXTRA])
        potential[i] = _potential(d, speed)
        # reward terms, reward.TERMS order (eqs. 11-15 and ours; see reward.reward_terms)
        dux, duy = x - bx, y - by
        along = robot_force[i, 0] * dux + robot_force[i, 1] * duy
        alt, reps = 0.0, 0.0
        for j in range(n):
            alt += force[i, j, 0] * (pos[i, j, 0] - mb[j, 0]) + force[i, j, 1] * (pos[i, j, 1] - mb[j, 1])
            reps += math.hypot(rep[i, j, 0], rep[i, j, 1])
        r3 = -(dt + (p[MAX_STEPS] - steps[i]) * dt) if violation else -dt  # a violation pays the time it cut short
        terms = (along, dt if along > 0.0 else 0.0, r3, 1.0 if success else 0.0, -alt, -reps * dt,
                 -(dux * dux + duy * duy) / dt, -math.hypot(ax - prev_accel[i, 0], ay - prev_accel[i, 1]),
                 potential[i] - potential_before, -prox, -1.0 if violation else 0.0)
        r = 0.0
        for t in range(N_TERMS):
            r += terms[t] * weights[t]
            sums[i, t] += terms[t]
        sums[i, N_TERMS] += r
        rewards[i] = r
        prev_accel[i, 0], prev_accel[i, 1] = ax, ay
        terminated = success or violation
        flags[i, 0] = terminated
        flags[i, 1] = not terminated and steps[i] >= p[MAX_STEPS]
        flags[i, 2], flags[i, 3], flags[i, 4] = success, violation, collided


# -- observation and shield -------------------------------------------------------------------------------
@njit(cache=True)
def observations(p: np.ndarray, pose: np.ndarray, vel: np.ndarray, count: np.ndarray, pos: np.ndarray,
                 mvel: np.ndarray, centre: np.ndarray, radius: np.ndarray, slot: np.ndarray, out: np.ndarray,
                 rows: np.ndarray) -> None:
    """``observation.vector_observation`` of the copies in ``rows`` into ``out`` (float32 rows)."""
    scale, limit = POS_SCALE, OBS_LIMIT
    order = np.empty(pos.shape[1], dtype=np.int64)
    d2 = np.empty(pos.shape[1])
    for i in rows:
        x, y, yaw = pose[i, 0], pose[i, 1], pose[i, 2]
        fyaw = yaw if p[TURN] > 0 else math.atan2(centre[i, 1] - y, centre[i, 0] - x)
        c, s = math.cos(fyaw), math.sin(fyaw)
        o = out[i]
        o[:] = 0.0
        o[0] = (c * (slot[i, 0] - x) + s * (slot[i, 1] - y)) / scale
        o[1] = (c * (slot[i, 1] - y) - s * (slot[i, 0] - x)) / scale
        o[2] = (c * (centre[i, 0] - x) + s * (centre[i, 1] - y)) / scale
        o[3] = (c * (centre[i, 1] - y) - s * (centre[i, 0] - x)) / scale
        o[4] = radius[i] / scale
        o[5], o[6] = (c * vel[i, 0] + s * vel[i, 1]) / p[MAX_SPEED], (c * vel[i, 1] - s * vel[i, 0]) / p[MAX_SPEED]
        o[7] = vel[i, 2] / p[MAX_YAW_RATE]
        o[8], o[9] = c, s
        rxh, ryh = p[ROOM_X] / 2, p[ROOM_Y] / 2
        o[10], o[11], o[12], o[13] = (rxh - x) / scale, (x + rxh) / scale, (ryh - y) / scale, (y + ryh) / scale
        n = min(count[i], MAX_MEMBERS)
        for j in range(count[i]):  # nearest first, ties in index order (a stable sort)
            dx, dy = pos[i, j, 0] - x, pos[i, j, 1] - y
            v = dx * dx + dy * dy
            m = j
            while m > 0 and d2[m - 1] > v:
                d2[m], order[m] = d2[m - 1], order[m - 1]
                m -= 1
            d2[m], order[m] = v, j
        for r in range(n):
            j = order[r]
            dx, dy = pos[i, j, 0] - x, pos[i, j, 1] - y
            b = 14 + MEMBER_FIELDS * r
            o[b] = (dx * c + dy * s) * (1.0 / scale)
            o[b + 1] = (dx * -s + dy * c) * (1.0 / scale)
            o[b + 2] = mvel[i, j, 0] * c + mvel[i, j, 1] * s
            o[b + 3] = mvel[i, j, 0] * -s + mvel[i, j, 1] * c
            o[b + 4] = 1.0
        o[39] = _remainder(yaw - fyaw) / math.pi
        for t in range(o.shape[0]):
            o[t] = min(max(o[t], -limit), limit)


@njit(cache=True)
def shield(obs: np.ndarray, actions: np.ndarray, clearance_min: float, brake_accel: float, max_speed: float,
           half_length: float, half_width: float, human_radius: float, out: np.ndarray) -> None:
    """``shield.shield_action`` for every row."""
    cl = np.empty(MAX_MEMBERS)
    tx = np.empty(MAX_MEMBERS)
    ty = np.empty(MAX_MEMBERS)
    order = np.empty(MAX_MEMBERS, dtype=np.int64)
    reach = math.hypot(half_length, half_width)
    for i in range(obs.shape[0]):
        out[i, :] = actions[i, :]
        k = 0
        for j in range(MAX_MEMBERS):
            b = 14 + MEMBER_FIELDS * j
            if not float(obs[i, b + 4]) > 0.5:
                continue
            px, py = float(obs[i, b]) * POS_SCALE, float(obs[i, b + 1]) * POS_SCALE
            dist = math.hypot(px, py)  # from the footprint's circumscribed circle (``shield.footprint_clearance``)
            norm = max(dist, 1e-9)
            v = dist - reach - human_radius
            tx_j, ty_j = px / norm, py / norm
            m = k
            while m > 0 and cl[m - 1] > v:
                cl[m], tx[m], ty[m], order[m] = cl[m - 1], tx[m - 1], ty[m - 1], order[m - 1]
                m -= 1
            cl[m], tx[m], ty[m], order[m] = v, tx_j, ty_j, j
            k += 1
        if k == 0:
            continue
        vx, vy = float(actions[i, 0]) * max_speed, float(actions[i, 1]) * max_speed
        speed = math.hypot(vx, vy)
        if speed > max_speed:
            vx, vy = vx * (max_speed / speed), vy * (max_speed / speed)
        for r in range(k):
            b = 14 + MEMBER_FIELDS * order[r]
            allow = math.sqrt(2.0 * brake_accel * max(cl[r] - clearance_min, 0.0))
            closing = (vx - float(obs[i, b + 2])) * tx[r] + (vy - float(obs[i, b + 3])) * ty[r]
            if closing > allow:
                vx, vy = vx - (closing - allow) * tx[r], vy - (closing - allow) * ty[r]
        out[i, 0] = min(max(vx / max_speed, -1.0), 1.0)
        out[i, 1] = min(max(vy / max_speed, -1.0), 1.0)
