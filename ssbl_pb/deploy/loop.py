"""The deploy loop: odometry + the newest tracked people -> the Vector observation (the simulator's layout) ->
the policy (with its smoothing and safety shield) -> the command clamp -> the robot, ``rate_hz`` times a second.

Safety, on by default: every command clamped to ``max_speed`` here, whatever the robot, and braked for members
out of view and for the base's range returns (``guards``); the run stops when a
tracked person comes within ``stop_distance`` of the footprint, when the newest frame is older than ``stale_s``,
when odometry is frozen for ``stale_s`` (its pose unchanged while its own velocity says the base moves), on any
exception, on SIGINT/SIGTERM/SIGHUP and on connection loss; every robot call is bounded; the base is stopped before
the loop returns in every case, and each shutdown step runs whatever the one before it did
(``faults.EXIT_CODES`` names how it ended). While fewer than two people are
known the robot turns in place to find the group (``search``); the run succeeds by the task's own rule
(``TaskParams``) applied to the estimated group.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core import observation as ob
from ..core.layouts import member_keep_out, slot_keep
from ..core.shield import ShieldParams, footprint_clearance
from ..core.task import TaskParams
from ..errors import Terminated
from ..params import RobotParams, SocialParams, WorldParams, _check, _positive
from ..perception.groups.estimate import GroupModel, member_arrays
from ..perception.groups.looks import ARRIVAL_MARGIN, CONFIRM_S, Looks, claim_rule
from ..perception.groups.observation_model import PerceptionParams
from .faults import EXIT_CODES, DeployFault, HumanTooClose, StaleFrame, StaleOdometry
from .frames import Frames
from .guards import Guards
from .log import RunLog, dynamics_columns
from .perceive import Perception, pose_at
from .robot import Robot, clamp_command


@dataclasses.dataclass(frozen=True)
class DeployParams:
    """The loop's rate and safety limits (flags of ``python -m ssbl_pb.deploy``)."""

    rate_hz: float = 1.0 / WorldParams.dt  # Hz: the policy's control period (0.1 s)
    max_speed: float = RobotParams.max_speed  # m/s clamp on the planar speed (NAOqi's default)
    stale_s: float = 0.5  # newest frame / odometry older than this stops the run (ROS cmd_vel muxes, lerobot)
    stop_distance: float = TaskParams.intimate_zone  # m between bodies: Hall's intimate zone
    duration_s: float = 90.0  # s: three simulated episodes (30 s). Deploy also searches (a full turn: 12.6 s), looks
    #   at members before a claim (up to LOOK_S each) and docks slowly: `mixed` lockstep joins took up to 57 s, and
    #   a five-person group approached from 6 m behind reached its place at 55 s, unclaimed when 60 s ran out
    settle_s: float = 0.5  # s standing still at start while the tracker confirms what is in view
    # the search, written once where the simulator's observation model runs it too (``PerceptionParams``):
    search_turn: float = PerceptionParams.search_turn  # rad/s in place while fewer than two people are known
    sidestep_s: float = PerceptionParams.sidestep_s  # s stepping sideways when one person hides the others ...
    sidestep_speed: float = PerceptionParams.sidestep_speed  # m/s ... 0.6 m: at 3-5 m that opens a person's width
    # ... up to this many in a row while that person stays the only one known: a pair in line 3-3.5 m ahead, one
    # sidestep opened too little (the observation model in the small map room: 9 % of 200 starts searched the whole
    # episode); the camera faces that person, and so the one behind, all the way
    sidestep_repeats: int = PerceptionParams.sidestep_repeats
    # s: success is claimed only when every member known was seen within this of the claim's first try (or since,
    # while the robot stays within the place's tolerance); else it looks at each one first (``looks.Looks``)
    confirm_s: float = CONFIRM_S
    first_frame_s: float = 5.0  # s allowed for the camera's first frame
    continue_after_success: bool = False  # hold the slot (policy running) until --duration instead of ending
    status_s: float = 1.0  # seconds between status lines (0: none)

    def __post_init__(self) -> None:
        _positive("deploy", self, "rate_hz", "max_speed", "stale_s", "stop_distance", "duration_s", "search_turn",
                  "first_frame_s")
        _check(self.rate_hz <= 50, "deploy", "rate_hz", self.rate_hz, "<= 50 Hz")
        _check(self.max_speed <= 0.55, "deploy", "max_speed", self.max_speed, "<= 0.55 m/s (Pepper's hardware max)")
        _check(self.settle_s >= 0, "deploy", "settle_s", self.settle_s, ">= 0")
        _check(self.status_s >= 0, "deploy", "status_s", self.status_s, ">= 0")
        _check(isinstance(self.sidestep_repeats, int) and self.sidestep_repeats >= 1, "deploy", "sidestep_repeats",
               self.sidestep_repeats, "an integer >= 1")
        _check(self.confirm_s > 0, "deploy", "confirm_s", self.confirm_s, "> 0 s")


ESTIMATE_MARGIN = 0.1  # m the policy's shield keeps beyond --stop-distance: the tracked people's error near the
#   robot (virtual Pepper, seeded lockstep runs: 0.01-0.03 m along the line of sight, 0.03-0.08 m across it for a
#   person just out of view) must not turn the policy's closest pass (0.5 m by the training shield) into a stop
MOVING = 0.02  # m/s and rad/s: a reported velocity above this must move the pose within ``stale_s`` (odometry at
#   10 Hz moves 2 mm a tick at this speed; a standing base's pose may not change at all, and is not stale)
DOCK_REACH = 0.1  # m beyond the slot tolerance within which, the policy having stopped, deploy takes the robot the
#   last centimetres to its estimated place (``_dock``): trained to stop within the tolerance (the episode ends
#   there), the policy stood 0.2-0.27 m from it, short of ``ARRIVAL_MARGIN``, until the run's time ran out
DOCK_SPEED = 0.06  # m/s: below the success rule's stop speed (0.1), so the robot may stop any tick


def deploy_shield(robot: RobotParams, social: SocialParams, task: TaskParams, stop_distance: float,
                  at_place: bool = False) -> ShieldParams:
    """The policy's safety shield on the robot: the training one (``ShieldParams.from_env``, ``at_place`` as the
    policy was trained), braking ``ESTIMATE_MARGIN`` before ``stop_distance`` when that is further out."""
    shield = ShieldParams.from_env(robot, social, task, at_place)
    return dataclasses.replace(shield, clearance_min=max(shield.clearance_min, stop_distance + ESTIMATE_MARGIN))


@dataclasses.dataclass
class Setup:
    """What the loop drives: the robot, the policy and the models it needs (all already checked)."""

    robot: Robot
    policy: Any  # ``predict(obs, state, episode_start, deterministic) -> (action, state)``
    perception: Perception
    frames: Frames
    robot_params: RobotParams = dataclasses.field(default_factory=RobotParams)
    social: SocialParams = dataclasses.field(default_factory=SocialParams)
    task: TaskParams = dataclasses.field(default_factory=TaskParams)
    groups: str = "calibrated"  # the group model the policy was trained with (``core.layouts.GROUP_MODELS``)
    waypoints: bool = False  # the policy was trained with waypoints in furnished rooms (``env.rooms.planner``)
    waypoints_near_group: bool = False  # ... shown up to the group's keep-out disc
    member_order: str = "nearest"  # the order of the observation's member blocks it was trained with


class DeployLoop:
    """Runs ``Setup`` until success, ``duration_s`` or a fault; ``run`` returns (outcome, message)."""

    def __init__(self, setup: Setup, params: DeployParams | None = None, log: RunLog | None = None,
                 now: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
                 status: Callable[[str], None] | None = None) -> None:
        self.s, self.p, self.log, self.now, self.sleep = setup, params or DeployParams(), log, now, sleep
        self.status = status
        self.shield = ShieldParams.of(setup)
        clearance = deploy_shield(setup.robot_params, setup.social, setup.task, self.p.stop_distance).clearance_min
        self.guards = Guards(self.shield, clearance, self.p.stop_distance, setup.frames)  # after the policy's shield
        self.period = 1.0 / self.p.rate_hz
        # the clamp of every command sent, whatever the robot implementation clamps itself
        self.limits = dataclasses.replace(setup.robot_params, max_speed=min(setup.robot_params.max_speed,
                                                                            self.p.max_speed))
        self._odo_pose: np.ndarray | None = None
        self._odo_fresh = -math.inf  # local time odometry was last seen consistent (moved, or says it stands)
        self.shield_steps = 0  # policy ticks, and those the shield changed the command in
        self.shield_interventions = 0
        self.outcome, self.message, self.stop_note = "exception", "", ""
        self._policy_state: Any = None
        self._approaching = False
        self._search_side = 0.0
        self._turned, self._last_yaw, self._sidestep_left, self._sidesteps = 0.0, None, 0, 0
        self.looks = Looks(self.p.confirm_s)  # looks at members not seen lately: before a claim, when stalled
        self.group = GroupModel(setup.social, slot_keep(setup.social, setup.robot_params.reach,
                                                        setup.task.intimate_zone, setup.task.route_margin),
                                paper=setup.groups == "paper",
                                # keypoint facings (MoveNet) may be far off; the colour detector's chest marker is not
                                robust=setup.groups != "paper" and not getattr(setup.perception, "torso", True))
        setup.perception.group_model = self.group  # the tracker records rests by its joining weight
        self._last_status, self._ticks_since = -math.inf, 0

    # -- one tick --------------------------------------------------------------------------------------------
    def _members(self, now: float) -> tuple[np.ndarray, np.ndarray, list[Any], float | None, int]:
        est, _ = self.s.perception.snapshot()
        if est is None or not est.members:
            return np.zeros((0, 2)), np.zeros((0, 2)), [], None, 0 if est is None else est.detections
        age = now - est.capture
        pos = np.array([m.pos + m.vel * age for m in est.members])
        return pos, np.array([m.vel for m in est.members]), est.members, age, est.detections

    def _act(self, pose: np.ndarray, vel: np.ndarray, pos: np.ndarray, mvel: np.ndarray, rest: np.ndarray,
             facing: np.ndarray | None = None, facing_std: np.ndarray | None = None
             ) -> tuple[np.ndarray, dict[str, Any]]:
        """The policy's body command for a known group (odometry-frame inputs), and what it saw."""
        s, fr = self.s, self.s.frames
        if not self._approaching:  # a new approach: fresh group model, policy filter and state
            self.group.reset()
            if hasattr(s.policy, "reset"):
                s.policy.reset()
            self._policy_state, self._approaching = None, True
            self.looks.new_approach()
        centre, radius, joining, slot = self.group.update(pos, pose[:2], rest, facing, facing_std)
        s.perception.centre0 = self.group.centre
        room = fr.room_pose(pose)
        rot = fr.room_from_odom[2]
        c, sn = math.cos(rot), math.sin(rot)
        mvel_room = mvel @ np.array([[c, sn], [-sn, c]])
        cy, sy = math.cos(room[2]), math.sin(room[2])
        vel_room = np.array([cy * vel[0] - sy * vel[1], sy * vel[0] + cy * vel[1], vel[2]])
        centre_room, slot_room = fr.room_points(np.array([centre, slot]))
        members_room = fr.room_points(pos)
        if s.waypoints:
            reach = s.robot_params.reach
            slot_room = fr.way_to(room, members_room, centre_room, slot_room, reach,
                                  member_keep_out(s.social, reach, s.task.intimate_zone), s.waypoints_near_group)
        frame = ob.approach_yaw(room, centre_room)
        obs = ob.vector_observation(room, vel_room, members_room, mvel_room, centre_room, radius, slot_room,
                                    fr.walls(room), s.robot_params.max_speed, s.robot_params.max_yaw_rate, frame,
                                    fr.scan(room, frame), s.member_order)
        start = np.array([self._policy_state is None])
        action, self._policy_state = s.policy.predict(obs, state=self._policy_state, episode_start=start,
                                                      deterministic=True)
        slot_dist = float(np.hypot(*(slot - pose[:2])))
        dock = self._dock(obs, np.asarray(action, dtype=float).ravel(), pose, centre, slot, slot_dist)
        action = action if dock is None else dock
        heading = math.remainder(math.atan2(centre[1] - pose[1], centre[0] - pose[0]) - pose[2], 2 * math.pi)
        cmd = self._command(action, heading)
        last = getattr(getattr(s.policy, "shield", None), "last", None)
        shield = last.row() if last is not None else None  # what the policy's shield changed this tick
        if shield is not None:
            shield["cmd_before"] = self._command(np.asarray(shield["before"]), heading).tolist()
        success = claim_rule(slot_dist, math.hypot(vel[0], vel[1]), heading, s.task)
        return cmd, {"centre": centre, "radius": radius, "joining": joining, "slot": slot, "slot_distance_m": slot_dist,
                     "heading_error_deg": math.degrees(heading), "action": np.asarray(action).ravel(),
                     "shield": shield, "dock": dock is not None, "success": success}

    def _dock(self, obs: np.ndarray, action: np.ndarray, pose: np.ndarray, centre: np.ndarray, slot: np.ndarray,
              slot_dist: float) -> np.ndarray | None:
        """The action that takes the robot the last centimetres to its estimated place at ``DOCK_SPEED`` (in the
        approach frame, through the policy's shield when it has one), when the policy has stopped (its action under
        the stop speed) within ``DOCK_REACH`` beyond the slot tolerance but not yet ``ARRIVAL_MARGIN`` inside it;
        else None."""
        s = self.s
        tol, top = s.task.slot_tolerance, s.robot_params.max_speed
        if not (tol - ARRIVAL_MARGIN <= slot_dist < tol + DOCK_REACH and len(action) >= 2
                and math.hypot(action[0], action[1]) * top < s.task.stop_speed):
            return None
        yaw = math.atan2(centre[1] - pose[1], centre[0] - pose[0])  # the approach frame: x toward the centre
        c, sn = math.cos(yaw), math.sin(yaw)
        d = slot - pose[:2]
        dock = action.copy()
        dock[:2] = np.array([c * d[0] + sn * d[1], -sn * d[0] + c * d[1]]) * (DOCK_SPEED / top / max(slot_dist, 1e-9))
        shield = getattr(s.policy, "shield", None)
        return dock if shield is None else np.asarray(shield(obs, dock), dtype=float)

    def _command(self, action: np.ndarray, heading: float) -> np.ndarray:
        """The body command (forward, left, turn) of a policy action, turning toward the group centre."""
        s = self.s
        a = np.zeros(3)
        a[:min(3, np.size(action))] = np.ravel(action)[:3]
        return np.array(ob.action_command(*a, heading, s.task.turn, s.task.heading_gain, s.robot_params.max_speed,
                                          s.robot_params.max_yaw_rate))

    def tick(self, t0: float, elapsed: float, late: bool) -> bool:
        """One control period; True when the run has succeeded."""
        s, p = self.s, self.p
        cpu0 = time.thread_time()
        s.perception.check()
        s.perception.step()
        odo = s.robot.odometry()
        s.frames.anchor(odo.pose)
        s.perception.odometry.append((odo.stamp, odo.pose))
        now = self.now()
        odom_ms = 1000.0 * (now - t0)
        self._check_odometry(odo, now)
        _, capture = s.perception.snapshot()
        if now - capture > p.stale_s:
            raise StaleFrame(f"newest camera frame is {now - capture:.2f} s old (limit {p.stale_s:g} s): camera "
                             f"frozen or frames not arriving")
        pos, mvel, members, age, detections = self._members(now)
        self.looks.saw(members, now)
        clearance = (footprint_clearance(pos - odo.pose[:2], float(odo.pose[2]), self.shield)[0] if len(pos)
                     else np.zeros(0))
        if len(clearance) and clearance.min() < p.stop_distance:
            raise HumanTooClose(f"a tracked person is {clearance.min():.2f} m from the robot "
                                f"(--stop-distance {p.stop_distance:g} m)")
        info: dict[str, Any] = {}
        if elapsed < p.settle_s:
            state, cmd = "settle", np.zeros(3)
        elif len(pos) < 2:
            s.perception.centre0 = None
            state, cmd = self._search(odo.pose, pos)
        else:
            _, rest, facing, facing_std = member_arrays(members)
            cmd, info = self._act(odo.pose, odo.velocity, pos, mvel, rest, facing, facing_std)
            held, look, k = self.looks.decide(members, now, info["success"], info["slot_distance_m"],
                                              math.hypot(*odo.velocity[:2]), s.task)
            state = "joined" if held else "dock" if info["dock"] else "approach"
            if info["success"] and not held:  # arrived by its estimate: it stands while the rule must hold
                state, cmd = "hold", np.array([0.0, 0.0, cmd[2]])  # (over qi the policy, still driving at 0.05
                #   m/s, took it back over the margin within the second, again and again: 3 of 20 joins unclaimed)
            if look is not None:  # a claim it cannot back yet ("confirm"), or stalled away from its place ("look")
                state, cmd = look, self._turn_to(pos[k], odo.pose)
        scan = s.robot.ranges() if hasattr(s.robot, "ranges") else None
        scan_pose = None if scan is None else pose_at(s.perception.odometry, scan.stamp)
        if scan is not None:  # the lasers' returns range the detector's people (the sonars' do not: no bearing)
            s.perception.ranges(scan.points[:len(scan.points) - scan.sonars], scan_pose)
        cmd, guarded = self.guards(cmd, scan, members, pos, odo.pose, age, now, info.get("slot_distance_m", math.inf),
                                   scan_pose)
        t_send = self.now()
        sent = s.robot.send(clamp_command(cmd, self.limits))
        t_sent = self.now()
        tick_ms = 1000.0 * (t_sent - t0)
        cpu_ms = 1000.0 * (time.thread_time() - cpu0)  # this thread's CPU: the rest of tick_ms was waiting
        events = s.robot.events() if hasattr(s.robot, "events") else []
        if self.log is not None:
            fr = s.frames
            self.log.write({
                "t": elapsed, "wall": time.time(), "state": state, **dynamics_columns(odo.pose, sent),
                "vel": odo.velocity, "room_pose": fr.room_pose(odo.pose), "map_pose": fr.map_pose(odo.pose),
                "cmd_policy": cmd, "humans": [{"id": m.id, "x": float(q[0]), "y": float(q[1]), "vx": float(m.vel[0]),
                                               "vy": float(m.vel[1]), "cov": m.cov, "seen": m.seen,
                                               "facing": m.facing,
                                               "facing_std": m.facing_std if math.isfinite(m.facing_std) else None}
                                              for m, q in zip(members, pos, strict=True)],
                **{k: v for k, v in info.items() if k != "success"}, "detections": detections,
                "min_clearance_m": float(clearance.min()) if len(clearance) else None,
                "estimate_age_ms": None if age is None else 1000.0 * age, "frame_age_ms": 1000.0 * (now - capture),
                "tick_ms": tick_ms, "tick_cpu_ms": cpu_ms, "odom_ms": odom_ms, "send_ms": 1000.0 * (t_sent - t_send),
                "late": late, "events": events, **guarded})
        self._report(now, elapsed, state, len(members), sum(m.seen for m in members), info)
        return state == "joined"

    def _check_odometry(self, odo: Any, now: float) -> None:
        """``StaleOdometry`` when the reading is older than ``stale_s`` by its stamp, or frozen: its pose has not
        changed for ``stale_s`` while its own velocity says the base moves (faster than ``MOVING``). A robot that
        stamps readings on receipt (NAOqi's getRobotPosition has no time stamp) is judged by the second alone."""
        p = self.p
        if now - odo.stamp > p.stale_s:
            raise StaleOdometry(f"odometry is {now - odo.stamp:.2f} s old (limit {p.stale_s:g} s)")
        pose = np.asarray(odo.pose, dtype=float)
        moving = bool(np.any(np.abs(np.asarray(odo.velocity, dtype=float)) > MOVING))
        if self._odo_pose is None or not moving or np.any(pose != self._odo_pose):
            self._odo_fresh = now
        self._odo_pose = pose
        if now - self._odo_fresh > p.stale_s:
            v = np.asarray(odo.velocity, dtype=float)
            raise StaleOdometry(f"odometry frozen: pose unchanged for {now - self._odo_fresh:.2f} s while the robot "
                                f"reports moving at ({v[0]:.2f}, {v[1]:.2f}) m/s, {v[2]:.2f} rad/s (limit "
                                f"{p.stale_s:g} s)")

    def _turn_to(self, point: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The command that turns in place toward ``point`` (at most ``search_turn`` rad/s)."""
        d = point - pose[:2]
        heading = math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi)
        turn = float(np.clip(self.s.task.heading_gain * heading, -self.p.search_turn, self.p.search_turn))
        return np.array([0.0, 0.0, turn])

    def _search(self, pose: np.ndarray, pos: np.ndarray) -> tuple[str, np.ndarray]:
        """Fewer than two people known: turn in place (toward the one known person's side first); after a full
        turn with still one person known (the others hidden behind them), step sideways for ``sidestep_s``
        while facing that person, for another line of sight, up to ``sidestep_repeats`` times in a row while they
        stay the only one, and turn again."""
        p = self.p
        if self._approaching or self._search_side == 0.0:  # a new search
            d = pos.mean(axis=0) - pose[:2] if len(pos) else np.array([1.0, 1.0])
            self._search_side = 1.0 if math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi) >= 0 else -1.0
            self._turned, self._last_yaw, self._sidestep_left, self._sidesteps = 0.0, None, 0, 0
        self._approaching = False
        if self._last_yaw is not None:
            self._turned += abs(math.remainder(pose[2] - self._last_yaw, 2 * math.pi))
        self._last_yaw = float(pose[2])
        again = self._sidestep_left == 0 and 0 < self._sidesteps < p.sidestep_repeats
        if len(pos) == 1 and (self._turned >= 2 * math.pi or again):
            self._sidesteps = self._sidesteps + 1 if again else 1
            self._turned, self._sidestep_left = 0.0, int(round(p.sidestep_s * p.rate_hz))
        if self._sidestep_left > 0 and len(pos) == 1:
            self._sidestep_left -= 1
            d = pos[0] - pose[:2]
            heading = math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi)
            turn = float(np.clip(self.s.task.heading_gain * heading, -p.search_turn, p.search_turn))
            return "sidestep", np.array([0.0, self._search_side * p.sidestep_speed, turn])
        return "search", np.array([0.0, 0.0, self._search_side * p.search_turn])

    def _report(self, now: float, elapsed: float, state: str, known: int, seen: int, info: dict[str, Any]) -> None:
        self._ticks_since += 1
        if self.status is None or not self.p.status_s or now - self._last_status < self.p.status_s:
            return
        rate = self._ticks_since / (now - self._last_status) if math.isfinite(self._last_status) else self.p.rate_hz
        self._last_status, self._ticks_since = now, 0
        slot = f"slot {info['slot_distance_m']:.2f} m" if "slot_distance_m" in info else "slot -"
        self.status(f"t {elapsed:5.1f} s  {rate:4.1f} Hz  humans {known} ({seen} in view)  {slot}  {state}")

    # -- the run ---------------------------------------------------------------------------------------------
    def _wait_first_frame(self) -> None:
        end = self.now() + self.p.first_frame_s
        while True:
            self.s.perception.check()
            self.s.perception.step()
            if math.isfinite(self.s.perception.snapshot()[1]):
                return
            if self.now() > end:
                raise StaleFrame(f"no camera frame within {self.p.first_frame_s:g} s")
            self.sleep(0.02)

    def run(self) -> tuple[str, str]:
        """Until success, ``duration_s`` or a fault; the base is stopped on every way out. Faults return
        (outcome, message) and keep them whatever the shutdown meets (its error, if any, in ``shutdown_error``);
        SIGINT/SIGTERM/SIGHUP and exceptions propagate after the stop."""
        s, p = self.s, self.p
        self.shutdown_error: str | None = None
        try:
            s.perception.start()
            self._wait_first_frame()
            start = self.now()
            k = 0
            while True:
                t0 = self.now()
                late = t0 - (start + k * self.period) > 0.5 * self.period
                elapsed = t0 - start
                if elapsed >= p.duration_s:
                    self.outcome, self.message = "duration", f"--duration {p.duration_s:g} s elapsed"
                    break
                if self.tick(t0, elapsed, late) and not p.continue_after_success:
                    self.outcome, self.message = "success", f"joined the group after {elapsed:.1f} s"
                    break
                k += 1
                if self.now() - (start + k * self.period) > self.period:  # far behind: do not burst to catch up
                    k = int((self.now() - start) / self.period) + 1
                self.sleep(max(0.0, start + k * self.period - self.now()))
        except DeployFault as fault:
            self.outcome, self.message = fault.outcome, str(fault)
        except Terminated as sig:  # SIGTERM, or SIGHUP (the terminal or ssh connection closed): cli.run
            self.outcome, self.message = "sigterm", str(sig.args[0]) if sig.args else "SIGTERM"
            raise
        except KeyboardInterrupt:
            self.outcome, self.message = "sigint", "SIGINT"
            raise
        except BaseException as exc:
            self.outcome, self.message = "exception", f"{type(exc).__name__}: {exc}"
            raise
        finally:
            failed = self._shutdown()
            if failed is not None:
                self.shutdown_error = f"{type(failed).__name__}: {failed}"
        if failed is not None and self.outcome in ("success", "duration"):
            # the run itself ended cleanly: the shutdown's first error is the one to report; a fault keeps its own
            self.outcome, self.message = "exception", self.shutdown_error or ""
            raise failed
        return self.outcome, self.message

    def _shutdown(self) -> BaseException | None:
        """Stop the base, the workers and the robot, each step whatever the one before it did (a camera left
        subscribed would refuse the next run); returns the first error that is not a ``DeployFault`` (a bug or a
        robot error: the caller reports it only when the run has no fault or error of its own). A ``DeployFault``
        from the stop (robot gone or frozen) becomes ``stop_note``. SIGINT, SIGTERM and SIGHUP meanwhile are
        ignored (the run is ending anyway; a second Ctrl-C must not cut the stop short)."""
        old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
                if sig is not None:
                    old[sig] = signal.signal(sig, signal.SIG_IGN)
        first: BaseException | None = None
        try:
            for name, step in (("stop", self.s.robot.stop), ("perception", self.s.perception.stop),
                               ("close", self.s.robot.close)):
                try:
                    step()
                except DeployFault as fault:
                    if name == "stop":
                        self.stop_note = f"stop not confirmed ({fault})"
                except Exception as exc:  # noqa: BLE001 - reported below; the next step must run
                    if name == "stop":
                        self.stop_note = f"stop not confirmed ({type(exc).__name__}: {exc})"
                    first = first or exc
        finally:
            for sig, handler in old.items():
                signal.signal(sig, handler)
        return first

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.outcome]


def status_printer(stream: Any = None) -> Callable[[str], None]:
    """Status lines on stderr: rewritten in place on a terminal, one line each otherwise."""
    stream = stream or sys.stderr
    tty = hasattr(stream, "isatty") and stream.isatty()

    def show(line: str) -> None:
        stream.write(("\r" + line + "\x1b[K") if tty else line + "\n")
        stream.flush()

    return show
