"""One step of the approaching task for N copies at once, composed of the compiled formulas of each module.

``step`` runs, per copy: the action as a base command (``observation.action_command``), the base
(``base.base_step``), the members (``humans.group_step``: SFFM eqs. 8-10), the free slot (``humans.free_slot``),
clearances (``base.footprint_distance``, ``base.wall_clearance``, ``obstacles.footprint_clearance``), the success
rule (``task.joined``), the shaping potential (``reward.route_length``, ``reward.slot_potential``) and the reward
terms (``reward.step_terms``, eqs. 11-15). ``observations`` writes the Vector observation (``observation.
fill_observation``, and the range scan ``obstacles.fill_scan`` when the observation has room for it). Nothing here
is a formula of its own: the single env is a batch of one (``ApproachGroupEnv`` runs ``batched.BatchedApproach(1)``)
and training a batch of N, so both run this code. Parameters travel as packed float arrays (``task_params``;
``humans.sffm_params``; ``base.BaseParams``); each copy's room as a row of ``room`` (its size, which distance field
of ``fields`` holds its obstacles, and the footprint's clearance to them after the last step).
Compiled on first use and cached beside the source (``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...core.base import base_step, footprint_distance, wall_clearance, wrap_angle
from ...core.humans import KEEP, RADIUS, free_slot, group_step
from ...core.layouts import slot_keep
from ...core.observation import BASE_SIZE, POS_SCALE, SCAN_RANGE, action_command, fill_observation, orders_by_bearing
from ...core.reward import N_TERMS, proximity_cost, route_length, slot_potential, step_terms
from ...core.task import TaskParams, joined
from ...params import RobotParams, SocialParams, WorldParams
from ..rooms.obstacles import CAP, fill_scan, footprint_clearance
from ..rooms.planner import in_sight, plan_distance, plan_map, way_clearances, way_length, waypoint

# the task's parameters as the compiled step reads them (``task_params``)
(MAX_SPEED, MAX_YAW_RATE, HALF_LENGTH, HALF_WIDTH, HUMAN_RADIUS, DT, HEADING_GAIN, SLOT_TOL, STOP_SPEED,
 HEADING_TOL, INTIMATE, BAND, MAX_STEPS, KEEP_OUT_EXTRA, TURN, PLAN_CLEARANCE, SIGHT_CLEARANCE, GEODESIC,
 BY_BEARING, N_TASK) = range(20)
# per-copy flags of the last step (COLLISION: with anything; OBSTACLE_COLLISION: with a wall or an obstacle)
TERMINATED, TRUNCATED, SUCCESS, VIOLATION, COLLISION, OBSTACLE_COLLISION, N_FLAGS = range(7)
# per-copy room, columns of ``room``: size (m), index into ``fields`` (-1: no obstacles) and the field's first
# node (m), the footprint's clearance to the obstacles after the last step (m, at most ``obstacles.CAP``), and
# (m) beyond which the copy's row of ``plans`` shows the way to the group (``planner``; 0: off), whether that
# plan is made (0: not yet, made the first time it is needed; 1: made; -1: no way), and what it is made from:
# the way in (m), the group's keep-out radius and its centre at the start (m); the robot's start (m), the steps
# the episode may last (``max_steps``, plus the furniture's detour once it ran them: ``detour_steps``) and
# whether that detour was added
(ROOM_X, ROOM_Y, FIELD, FIELD_X0, FIELD_Y0, OBSTACLE, PLAN, PLANNED, WAY_X, WAY_Y, KEEP_OUT, PLAN_CX, PLAN_CY,
 START_X, START_Y, STEP_LIMIT, DETOUR_ADDED, N_ROOM) = range(18)


def task_params(world: WorldParams, robot: RobotParams, social: SocialParams, task: TaskParams,
                member_order: str = "nearest") -> np.ndarray:
    """The parameters ``step`` and ``observations`` read besides the base's and the SFFM's, packed
    (``member_order``: the observation's, ``observation.MEMBER_ORDERS``)."""
    p = np.zeros(N_TASK)
    for k, v in {MAX_SPEED: robot.max_speed, MAX_YAW_RATE: robot.max_yaw_rate, HALF_LENGTH: robot.length / 2,
                 HALF_WIDTH: robot.width / 2, HUMAN_RADIUS: social.human_radius, DT: world.dt,
                 HEADING_GAIN: task.heading_gain, SLOT_TOL: task.slot_tolerance, STOP_SPEED: task.stop_speed,
                 HEADING_TOL: math.radians(task.heading_tolerance_deg), INTIMATE: task.intimate_zone,
                 BAND: task.proximity_band, MAX_STEPS: task.max_steps,
                 KEEP_OUT_EXTRA: slot_keep(social, robot.reach, task.intimate_zone, task.route_margin),
                 TURN: float(task.turn), PLAN_CLEARANCE: way_clearances(robot.reach)[0],
                 SIGHT_CLEARANCE: way_clearances(robot.reach)[1], GEODESIC: float(task.geodesic_route),
                 BY_BEARING: float(orders_by_bearing(member_order))}.items():
        p[k] = v
    return p


@njit(cache=True)
def heading_error(pose: np.ndarray, centre: np.ndarray) -> float:
    """Angle (rad) from the robot's heading to the conversation centre."""
    return wrap_angle(math.atan2(centre[1] - pose[1], centre[0] - pose[0]) - pose[2])


@njit(cache=True)
def clearances(tp: np.ndarray, pose: np.ndarray, n: int, pos: np.ndarray, out: np.ndarray) -> None:
    """Gap (m) between the footprint and each member's body circle (negative when overlapping) into ``out``."""
    for j in range(n):
        d, _, _ = footprint_distance(pos[j, 0] - pose[0], pos[j, 1] - pose[1], pose[2], tp[HALF_LENGTH],
                                     tp[HALF_WIDTH])
        out[j] = d - tp[HUMAN_RADIUS]


@njit(cache=True)
def static_clearance(tp: np.ndarray, pose: np.ndarray, room: np.ndarray, fields: np.ndarray) -> tuple[float, float]:
    """The footprint's clearance (m) to the nearest wall and to the nearest obstacle (``obstacles.CAP`` when none
    is within it) for a copy whose ``room`` row is given."""
    x, y, yaw = pose[0], pose[1], pose[2]
    walls = wall_clearance(x, y, yaw, tp[HALF_LENGTH], tp[HALF_WIDTH], room[ROOM_X], room[ROOM_Y])
    k = int(room[FIELD])
    if k < 0:
        return min(walls), CAP
    return min(walls), footprint_clearance(fields[k], room[FIELD_X0], room[FIELD_Y0], x, y, yaw, tp[HALF_LENGTH],
                                           tp[HALF_WIDTH])


@njit(cache=True)
def make_plan(tp: np.ndarray, row: np.ndarray, field: np.ndarray, plan: np.ndarray) -> None:
    """A copy's way to its group (``planner.plan_map`` from its ``room`` row into ``plan``); ``row[PLANNED]``
    becomes 1 (made) or -1 (no way)."""
    made = plan_map(field, row[FIELD_X0], row[FIELD_Y0], row[ROOM_X], row[ROOM_Y], tp[PLAN_CLEARANCE], row[PLAN_CX],
                    row[PLAN_CY], row[KEEP_OUT], row[WAY_X], row[WAY_Y], plan)
    row[PLANNED] = 1.0 if made else -1.0


@njit(cache=True)
def _round_group(tp: np.ndarray, pose: np.ndarray, slot: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """Length (m) of the way to the slot round the group (``reward.route_length``)."""
    return route_length(pose[0], pose[1], slot[0], slot[1], centre[0], centre[1], radius + tp[KEEP_OUT_EXTRA])


@njit(cache=True)
def route_to_slot(tp: np.ndarray, pose: np.ndarray, slot: np.ndarray, centre: np.ndarray, radius: float,
                  row: np.ndarray, plan: np.ndarray) -> float:
    """Length (m) of the shaping's way to the slot: round the group (``reward.route_length``) and, with
    ``geodesic_route`` in a room whose plan is made, outside the group's keep-out disc also round the furniture
    (the plan's way to the way in, then in); never shorter than the way round the group. inf where the plan
    does not reach the robot (inside an obstacle's margin, or cut off): the potential then stays as it was.

    Ours: round the group only, the shaping paid for driving at a desk between the robot and its
    group, and the policy pushed against the shield there until the time-out."""
    keep = radius + tp[KEEP_OUT_EXTRA]
    d = _round_group(tp, pose, slot, centre, radius)
    if tp[GEODESIC] > 0 and row[PLANNED] > 0 and math.hypot(pose[0] - row[PLAN_CX],
                                                              pose[1] - row[PLAN_CY]) > row[KEEP_OUT]:
        way = plan_distance(plan, row[FIELD_X0], row[FIELD_Y0], pose[0], pose[1])
        d = max(d, way + route_length(row[WAY_X], row[WAY_Y], slot[0], slot[1], centre[0], centre[1], keep))
    return d


@njit(cache=True)
def potential(tp: np.ndarray, pose: np.ndarray, slot: np.ndarray, centre: np.ndarray, radius: float,
              speed: float, row: np.ndarray, plan: np.ndarray, previous: float) -> float:
    """The shaping potential of a state: ``slot_potential`` of ``route_to_slot``; where that is inf, ``previous``
    (the potential keeps its value), or with no previous (NaN: an episode's start) the way round the group's."""
    d = route_to_slot(tp, pose, slot, centre, radius, row, plan)
    if d < np.inf:
        return slot_potential(d, speed)
    return previous if previous == previous else slot_potential(_round_group(tp, pose, slot, centre, radius), speed)


@njit(cache=True)
def step(tp: np.ndarray, bp: np.ndarray, sp: np.ndarray, weights: np.ndarray, actions: np.ndarray,
         pose: np.ndarray, vel: np.ndarray, queue: np.ndarray, count: np.ndarray, pos: np.ndarray, mvel: np.ndarray,
         myaw: np.ndarray, centre0: np.ndarray, centre: np.ndarray, gscal: np.ndarray, ring_off: np.ndarray,
         comfort: np.ndarray, force: np.ndarray, rep: np.ndarray, robot_force: np.ndarray, steps: np.ndarray,
         prev_accel: np.ndarray, clearance: np.ndarray, slot: np.ndarray, potentials: np.ndarray, sums: np.ndarray,
         terms: np.ndarray, rewards: np.ndarray, flags: np.ndarray, room: np.ndarray, fields: np.ndarray,
         plans: np.ndarray, aim: np.ndarray) -> None:
    """One step of every copy (the arrays of ``batched.BatchedApproach``, updated in place); ``terms`` gets each
    copy's unweighted reward terms, ``flags`` (terminated, truncated, success, violation, collision, obstacle
    collision). ``aim`` (N, 2): the point each robot turns to face and whose direction is its actions' frame,
    the conversation centre as the robot knows it (``centre`` itself, or the perceived one)."""
    dt = tp[DT]
    after = np.empty(pos.shape[1])
    for i in range(pose.shape[0]):
        a2 = actions[i, 2] if actions.shape[1] > 2 else 0.0
        fx, fy, w = action_command(actions[i, 0], actions[i, 1], a2, heading_error(pose[i], aim[i]),
                                   tp[TURN] > 0, tp[HEADING_GAIN], tp[MAX_SPEED], tp[MAX_YAW_RATE])
        n = count[i]
        robot_before, vel_before = pose[i, :2].copy(), vel[i, :2].copy()
        members_before = pos[i, :n].copy()
        potential_before = potentials[i]
        base_step(bp[0], bp[1], bp[2], bp[3], bp[4], int(bp[5]), bp[6], bp[7], pose[i], vel[i], queue[i], fx, fy, w)
        x, y = pose[i, 0], pose[i, 1]
        group_step(sp, i, x, y, count, pos, mvel, myaw, centre0, centre, gscal, ring_off, comfort, force, rep,
                   robot_force)
        steps[i] += 1
        radius = gscal[i, RADIUS]
        slot[i, 0], slot[i, 1] = free_slot(n, pos[i], centre[i, 0], centre[i, 1], radius,
                                           gscal[i, KEEP], x, y, True)
        clearances(tp, pose[i], n, pos[i], after)
        wall, room[i, OBSTACLE] = static_clearance(tp, pose[i], room[i], fields)
        nearest = after[:n].min()
        static = wall <= 0.0 or room[i, OBSTACLE] <= 0.0
        collided = nearest <= 0.0 or static
        violation = collided or nearest < tp[INTIMATE]
        speed = math.hypot(vel[i, 0], vel[i, 1])
        success = joined(violation, math.hypot(slot[i, 0] - x, slot[i, 1] - y), speed,
                         heading_error(pose[i], centre[i]), tp[SLOT_TOL], tp[STOP_SPEED], tp[HEADING_TOL])
        accel = (vel[i, :2] - vel_before) / dt
        potentials[i] = potential(tp, pose[i], slot[i], centre[i], radius, speed, room[i],
                                  plans[min(i, plans.shape[0] - 1)], potential_before)
        prox = proximity_cost(clearance[i, :n], after[:n], tp[INTIMATE], tp[BAND])
        clearance[i, :n] = after[:n]
        t = step_terms(robot_force[i, :2], pose[i, :2] - robot_before, force[i, :n], pos[i, :n] - members_before,
                       rep[i, :n], dt, accel, prev_accel[i], potential_before, potentials[i], success, violation,
                       prox, (room[i, STEP_LIMIT] - steps[i]) * dt, speed)
        r = 0.0
        for k in range(N_TERMS):
            r += t[k] * weights[k]
            sums[i, k] += t[k]
            terms[i, k] = t[k]
        sums[i, N_TERMS] += r
        rewards[i] = r
        prev_accel[i, 0], prev_accel[i, 1] = accel[0], accel[1]
        done = success or violation
        flags[i, TERMINATED] = done
        if not done and steps[i] >= room[i, STEP_LIMIT] and room[i, DETOUR_ADDED] == 0 and room[i, FIELD] >= 0:
            room[i, DETOUR_ADDED] = 1.0  # known at the start; worked out only for the episodes that need it
            room[i, STEP_LIMIT] += detour_steps(tp, room[i], fields[int(room[i, FIELD])])
        flags[i, TRUNCATED] = not done and steps[i] >= room[i, STEP_LIMIT]
        flags[i, SUCCESS], flags[i, VIOLATION], flags[i, COLLISION] = success, violation, collided
        flags[i, OBSTACLE_COLLISION] = static


@njit(cache=True)
def detour_steps(tp: np.ndarray, row: np.ndarray, field: np.ndarray) -> int:
    """Steps the room's obstacles add to the way from the episode's start to the group's way in: the geodesic
    distance (``planner.way_length``) through the room with its obstacles minus the same through the empty room
    (same walls, same keep-out disc, same grid metric), driven at the top speed. An episode in a furnished room
    may last ``max_steps`` plus these: the paper's 30 s were set for starts 2.5-5.5 m from the group in an empty
    room, and a start as far in a room whose furniture makes the way 10 m long ran out of time while driving
    (12 of the 29 failures of mixed groups in the Willow Garage west rooms)."""
    length = np.empty(2)
    for k, obstacles in enumerate((True, False)):
        length[k] = way_length(field, row[FIELD_X0], row[FIELD_Y0], row[ROOM_X], row[ROOM_Y], tp[PLAN_CLEARANCE],
                               row[PLAN_CX], row[PLAN_CY], row[KEEP_OUT], row[WAY_X], row[WAY_Y], row[START_X],
                               row[START_Y], obstacles)
    if not (length[0] < np.inf and length[1] < np.inf):
        return 0
    return int(math.ceil(max(length[0] - length[1], 0.0) / (tp[MAX_SPEED] * tp[DT])))


@njit(cache=True)
def observations(tp: np.ndarray, pose: np.ndarray, vel: np.ndarray, count: np.ndarray, pos: np.ndarray,
                 mvel: np.ndarray, centre: np.ndarray, gscal: np.ndarray, slot: np.ndarray, room: np.ndarray,
                 fields: np.ndarray, plans: np.ndarray, out: np.ndarray, rows: np.ndarray) -> None:
    """The Vector observation of the copies in ``rows`` into ``out`` (float32 rows; columns beyond
    ``observation.BASE_SIZE`` get the range scan). A copy with a plan (``room[i, PLAN]``) whose straight way to
    the slot is not free sees the plan's waypoint in the slot's entries (``planner``); the plan is made the first
    time it is needed."""
    rays = out.shape[1] - BASE_SIZE
    for i in rows:
        x, y, yaw = pose[i, 0], pose[i, 1], pose[i, 2]
        frame = yaw if tp[TURN] > 0 else math.atan2(centre[i, 1] - y, centre[i, 0] - x)
        n = count[i]
        rx, ry = room[i, ROOM_X], room[i, ROOM_Y]
        fill_observation(out[i], x, y, yaw, vel[i, 0], vel[i, 1], vel[i, 2], pos[i, :n], mvel[i, :n], centre[i, 0],
                         centre[i, 1], gscal[i, RADIUS], slot[i, 0], slot[i, 1],
                         (rx / 2 - x, x + rx / 2, ry / 2 - y, y + ry / 2), tp[MAX_SPEED], tp[MAX_YAW_RATE], frame,
                         tp[BY_BEARING] > 0)
        k = int(room[i, FIELD])
        if rays > 0:
            fill_scan(out[i], BASE_SIZE, rays, k >= 0, fields[max(k, 0)], room[i, FIELD_X0], room[i, FIELD_Y0], x,
                      y, frame, SCAN_RANGE, rx, ry)
        if room[i, PLAN] > 0 and k >= 0 and math.hypot(x - centre[i, 0], y - centre[i, 1]) > room[i, PLAN]:
            x0, y0 = room[i, FIELD_X0], room[i, FIELD_Y0]
            if not in_sight(fields[k], x0, y0, x, y, slot[i, 0], slot[i, 1], tp[SIGHT_CLEARANCE]):
                if room[i, PLANNED] == 0:  # first needed: most episodes never lose sight of their slot
                    make_plan(tp, room[i], fields[k], plans[i])
                wx, wy, found = waypoint(plans[i], x0, y0, x, y) if room[i, PLANNED] > 0 else (x, y, False)
                if found:
                    c, s = math.cos(frame), math.sin(frame)
                    out[i, 0] = (c * (wx - x) + s * (wy - y)) / POS_SCALE
                    out[i, 1] = (c * (wy - y) - s * (wx - x)) / POS_SCALE
