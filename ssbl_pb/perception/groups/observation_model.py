"""The group as the robot would perceive it, in simulation: an observation model for the engine.

On the robot the policy does not read the true state: deploy's perception detects the people in Pepper's 56 deg
camera, projects them to the ground, tracks them (``perception.tracking.tracker``, ego-motion compensated), remembers
the ones out of view where it last estimated them, and computes the group's centre, o-space radius and free
slot from those estimates (``perception.groups.estimate``). This module runs that same pipeline from the simulator's
state, with the camera replaced by a model of the detector's chain (``PerceptionParams``: by default a real
Pepper's, MoveNet on people; ``preset("colour")`` the virtual Pepper's colour detector on box proxies): a member can
be detected when it is in range with at least ``min_visible`` of its torso's width (MoveNet's: all of it and
a margin, as deploy keeps its boxes; the colour detector's: ``group.MIN_VISIBLE``, deploy completes the cut torso,
``deploy.perceive.complete_cut_torsos``, with ``partial_std_m`` more noise across the line of sight) inside the
image and no more than ``hidden_fraction`` of it hidden behind nearer people; it is then missed with probability
``miss_prob`` and placed with bearing noise and range noise (the lasers' within their reach, else growing with
distance). Its facing (relative to its line of sight) is measured with ``facing_std_deg`` of noise when its front is
toward the camera (within ``facing_front_deg``), and with ``facing_back_std_deg`` from further round.
Everything after the detections is deploy's code itself: ``GroupTracker.update`` (the Kalman tracker with deploy's
settings for the chain, ``group.TRACKER`` or ``TRACKER_KEYPOINTS``, and its memory of people out of view) and
``GroupModel.update`` (centre, radius, joining weight, free slot), called as ``deploy.loop.DeployLoop`` calls them.

While fewer than two people are known, deploy does not run the policy: it turns in place to find the group, and
after a full turn with one person in sight steps sideways for another line of sight (``DeployLoop._search``).
``PerceivedGroups.steer`` gives the engine the same, and deploy's looks (``looks.Looks``, the same code): at the
place it estimates, before it would claim success, it turns in place toward each member not seen lately, and
after standing away from that place for a while toward the one seen longest ago. The engine also keeps deploy's
range guard for the members the lasers see (``BatchedApproach._range_guard``). Not modelled: deploy's docking
the last centimetres, its 0.5 s settle at the start, its other guards (``deploy.guards``: the clearance from
members out of view, the memory of returns in the lasers' blind sectors, the sonars), duplicate and false tracks,
and the estimate's latency (one frame, ~60 ms).
Seeded per copy, apart from the env's own generator, so an episode's start is the same with the model on or off.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ...core import observation as ob
from ...core.humans import MAX_HUMANS, N_SCALARS, RADIUS
from ...core.range_sensors import lasers_see_body
from ...params import ConfigError, RobotParams, SocialParams, _check, from_dict
from ..camera import sim_camera
from .estimate import (
    BODY_HEIGHT,
    KEYPOINT_GROUP,
    MIN_VISIBLE,
    TORSO_HALF,
    TRACKER,
    TRACKER_KEYPOINTS,
    GroupModel,
    GroupParams,
    GroupTracker,
    member_arrays,
)
from .looks import CONFIRM_S, Looks, claim_rule

# QVGA, the resolution deploy subscribes (``deploy.naoqi.NaoqiParams.resolution``)
IMAGE_SIZE = (320, 240)


# parts of the Vector observation ``oracle`` can give from the true state instead (diagnostics: what each part of the
# perceived group costs, tools/ablate_perception.py), by their columns: the member blocks (positions, velocities,
# presence), the place, and the group's centre with its o-space radius
ORACLE_COLUMNS = {"members": slice(ob.MEMBERS, ob.HEADING), "place": slice(ob.SLOT_X, ob.SLOT_Y + 1),
                  "centre": slice(ob.CENTRE_X, ob.OSPACE_RADIUS + 1)}
ORACLE_PARTS = tuple(ORACLE_COLUMNS)
DETECTORS = ("movenet", "colour")  # the chains modelled: a real Pepper's (MoveNet on people), the virtual Pepper's
#   colour detector on box proxies


@dataclasses.dataclass(frozen=True)
class PerceptionParams:
    """The detector's model and the search turn (``deploy.loop.DeployParams.search_turn``). The defaults are the
    chain a real Pepper runs, MoveNet's (``detector: movenet``), measured against the virtual Pepper's bodies;
    ``preset("colour")`` gives the colour detector's on box proxies. docs/benchmarks.md, "The observation model",
    says where each number comes from (``tools/fit_observation.py`` measures them)."""

    # deploy's tracker, group memory and centre for this chain: keypoint tracks (``estimate.TRACKER_KEYPOINTS``), a
    # memory that expects a person only where perceive keeps the box (``KEYPOINT_GROUP``) and the centre robust to a
    # facing far off (``robust_facing_centre``), as ``deploy.perceive`` and ``deploy.loop`` choose them for MoveNet
    detector: str = "movenet"
    # MoveNet on bodies: ``tools/fit_observation.py`` on 40 lockstep runs (20 default, 20 mixed; docs/
    # benchmarks_movenet.md, "The observation model"). Within the lasers' reach (3 m: naoqi_driver's range,
    # ``deploy.ranges.RangeParams.laser_max``) the lasers range people (robust std 2-18 mm), beyond it the keypoints
    # (0.09-0.20 m at 3-6 m, 4.5 % of the range)
    laser_reach_m: float = 3.0  # m: people nearer are ranged with ``laser_std_m`` (0: no lasers, the colour chain)
    laser_std_m: float = 0.005  # m
    range_std_m: float = 0.0  # m: range noise of a detection beyond the lasers' reach ...
    range_std_per_m: float = 0.045  # ... growing by this per metre of distance
    bearing_std_deg: float = 0.8  # deg: bearing noise
    miss_prob: float = 0.06  # a person in plain sight (whole in the image, nobody in front) is not detected
    min_visible: float = 0.89  # share of the torso's width plus the chain's edge margin inside the image at which
    #   half as many are detected as in plain sight (perceive drops MoveNet's cut boxes; the colour chain completes
    #   cut torsos from a third)
    # share of the torso's width plus the edge margin inside the image at which MoveNet still finds a person the
    # image's side cuts, kept where a laser places them (within ``laser_reach_m``, ``range_sensors.lasers_see_body``;
    # deploy.perceive: the keypoints of half a body tell neither range, bearing nor facing). Ours, not measured:
    # MoveNet finds people with half their width in the image (0: such people are dropped, the colour chain)
    cut_share: float = 0.5
    hidden_fraction: float = 0.61  # share of a torso's width hidden behind nearer people at which half as many are
    #   detected as in plain sight
    partial_std_m: float = 0.04  # m across the line of sight for a torso completed beyond the image's side (its
    #   apparent width taken as the mean over facings: off by at most 0.07 m; the colour chain)
    facing_std_deg: float = 10.5  # deg: facing noise of a person whose front the camera sees ...
    facing_front_deg: float = 80.0  # ... within this angle of looking at the robot; from further round ...
    facing_back_std_deg: float = 12.5  # ... with this (inf: unknown)
    facing_flip_prob: float = 0.11  # a measured facing turned by 180 deg (keypoints that mistake front for back;
    #   deploy's facing filter keeps such a mode for a while: 9 % of front views, 14 % of back views)
    search_turn: float = 0.5  # rad/s in place while fewer than two people are known (half NAOqi's default; deploy
    #   takes these search values as its own defaults, DeployParams)
    sidestep_s: float = 3.0  # s sideways after a full turn with one person known ... (DeployParams.sidestep_s)
    sidestep_speed: float = 0.2  # m/s ... (DeployParams.sidestep_speed)
    sidestep_repeats: int = 3  # ... up to this many in a row (DeployParams.sidestep_repeats)
    sidestep_clearance: float = 0.4  # m: a sidestep goes only where the footprint keeps this from walls and furniture
    confirm_s: float = CONFIRM_S  # s: a claim is backed by members seen this long before it (Looks.confirm_s)
    # diagnostics only: these ``ORACLE_PARTS`` of the observation come from the true state (the search, the looks
    # and the success rule stay perception's); () for the chain a robot runs
    oracle: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _check(self.detector in DETECTORS, "perception", "detector", self.detector, f"one of {list(DETECTORS)}")
        _check(isinstance(self.min_visible, int | float) and 0 < self.min_visible <= 1, "perception",
               "min_visible", self.min_visible, "a share in (0, 1]")
        for name in ("range_std_m", "range_std_per_m", "bearing_std_deg", "facing_std_deg", "partial_std_m",
                     "laser_reach_m", "laser_std_m"):
            v = getattr(self, name)
            _check(isinstance(v, int | float) and math.isfinite(v) and v >= 0, "perception", name, v,
                   "a finite number >= 0")
        _check(isinstance(self.cut_share, int | float) and 0 <= self.cut_share <= 1, "perception", "cut_share",
               self.cut_share, "a share in [0, 1] (0: off)")
        for name in ("miss_prob", "facing_flip_prob"):
            v = getattr(self, name)
            _check(isinstance(v, int | float) and 0 <= v < 1, "perception", name, v, "a probability in [0, 1)")
        _check(isinstance(self.facing_back_std_deg, int | float) and self.facing_back_std_deg >= 0, "perception",
               "facing_back_std_deg", self.facing_back_std_deg, "a number >= 0 (inf: unknown)")
        _check(isinstance(self.facing_front_deg, int | float) and 0 <= self.facing_front_deg <= 180, "perception",
               "facing_front_deg", self.facing_front_deg, "degrees in [0, 180]")
        _check(isinstance(self.hidden_fraction, int | float) and 0 <= self.hidden_fraction <= 1, "perception",
               "hidden_fraction", self.hidden_fraction, "a fraction in [0, 1]")
        _check(isinstance(self.search_turn, int | float) and 0 < self.search_turn <= 2, "perception",
               "search_turn", self.search_turn, "rad/s in (0, 2]")
        _check(isinstance(self.sidestep_s, int | float) and 0 <= self.sidestep_s <= 30, "perception",
               "sidestep_s", self.sidestep_s, "seconds in [0, 30]")
        _check(isinstance(self.sidestep_speed, int | float) and 0 <= self.sidestep_speed <= 0.55, "perception",
               "sidestep_speed", self.sidestep_speed, "m/s in [0, 0.55]")
        _check(isinstance(self.sidestep_repeats, int) and self.sidestep_repeats >= 1, "perception",
               "sidestep_repeats", self.sidestep_repeats, "an integer >= 1")
        _check(isinstance(self.sidestep_clearance, int | float) and self.sidestep_clearance >= 0, "perception",
               "sidestep_clearance", self.sidestep_clearance, "metres >= 0")
        _check(isinstance(self.confirm_s, int | float) and self.confirm_s > 0, "perception", "confirm_s",
               self.confirm_s, "seconds > 0")
        _check(isinstance(self.oracle, tuple) and all(p in ORACLE_PARTS for p in self.oracle), "perception",
               "oracle", self.oracle, f"a list of {list(ORACLE_PARTS)} (empty: none)")

    @property
    def keypoints(self) -> bool:
        """The chain ranges and faces people from keypoints (MoveNet)."""
        return self.detector == "movenet"

    @classmethod
    def preset(cls, name: str) -> PerceptionParams:
        """The model of a detector's chain: ``movenet`` (the defaults) or ``colour``."""
        if name not in DETECTORS:
            fields = [f.name for f in dataclasses.fields(cls)]
            raise ConfigError(f"perception = {name!r}: expected false, true, one of {list(DETECTORS)} or a mapping "
                              f"of {fields}")
        return cls(**COLOUR) if name == "colour" else cls()

    @classmethod
    def of(cls, value: Any) -> PerceptionParams | None:
        """The env's ``perception`` argument: None/False (off: the true state), True (these defaults), a preset's
        name (``movenet``, ``colour``), a dict of fields (``preset``: the name whose values it changes) or an
        instance."""
        if value is None or value is False:
            return None
        if value is True:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            return cls.preset(value)
        if isinstance(value, dict):
            fields = dict(value)
            base = cls.preset(str(fields.pop("preset", "movenet")))
            return from_dict(cls, {**dataclasses.asdict(base), **fields}, "perception")
        fields = [f.name for f in dataclasses.fields(cls)]
        raise ConfigError(f"perception = {value!r}: expected false, true, one of {list(DETECTORS)} or a mapping of "
                          f"{fields}")


# the colour detector against the virtual Pepper's box proxies (tools/bench_deploy.py --lockstep, mixed, 10 runs):
# detected members' position error median 0.035 m at 1-2 m, 0.045 m at 2-3 m, 0.05 m at 3-4 m, 0.11 m at 4-6 m; a
# Gaussian's median radial error is 1.18 sigma, so sigma ~0.03 m at 1.5 m to ~0.07 m at 5 m; misses 3.2 % of
# frames; of the members whose line of sight passes within a torso's half-width of a nearer one, 56 % detected; the
# facing from the chest marker (front) and the torso's outline (back)
COLOUR = {"detector": "colour", "laser_reach_m": 0.0, "range_std_m": 0.01, "range_std_per_m": 0.012,
          "bearing_std_deg": 0.5, "miss_prob": 0.03, "min_visible": MIN_VISIBLE, "hidden_fraction": 0.75,
          "facing_std_deg": 10.0, "facing_back_std_deg": 30.0, "facing_flip_prob": 0.0, "cut_share": 0.0}


def hidden_share(xy: np.ndarray, halfwidth: float) -> np.ndarray:
    """Per robot-frame point (n, 2), the share of its torso's width (``halfwidth`` either side, across the line of
    sight) that people nearer the camera by more than 0.2 m cover (their torsos alike), sampled at 21 points."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    rng = np.maximum(np.hypot(xy[:, 0], xy[:, 1]), 1e-3)
    bearing, half = np.arctan2(xy[:, 1], xy[:, 0]), np.arctan2(halfwidth, rng)
    out = np.zeros(len(xy))
    for k in range(len(xy)):
        near = rng < rng[k] - 0.2
        if not near.any():
            continue
        rays = bearing[k] + half[k] * np.linspace(-1.0, 1.0, 21)
        gap = np.abs(np.remainder(rays[:, None] - bearing[near][None, :] + math.pi, 2 * math.pi) - math.pi)
        out[k] = float((gap <= half[near][None, :]).any(axis=1).mean())
    return out


def image_share(xy: np.ndarray, camera: Any, halfwidth: float, height: float, max_range: float) -> np.ndarray:
    """Per robot-frame point (n, 2), the share of a torso's width (``halfwidth`` either side across the line of
    sight, at ``height``) inside ``camera``'s image; 0 behind the camera or beyond ``max_range``."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    rng = np.hypot(xy[:, 0], xy[:, 1])
    across = np.column_stack([-xy[:, 1], xy[:, 0]]) / np.maximum(rng, 1e-6)[:, None] * halfwidth
    u = [camera.robot_to_pixel(np.column_stack([side, np.full(len(xy), height)]))[:, 0]
         for side in (xy - across, xy + across)]
    lo, hi = np.minimum(u[0], u[1]), np.maximum(u[0], u[1])
    inside = np.minimum(hi, camera.width - 1) - np.maximum(lo, 1)
    share = np.clip(inside / np.maximum(hi - lo, 1e-6), 0.0, 1.0)
    ok = np.isfinite(share) & (xy[:, 0] - halfwidth > 0) & (rng <= max_range)
    return np.where(ok, share, 0.0)


def detect(xy: np.ndarray, visible: np.ndarray, params: PerceptionParams, rng: np.random.Generator,
           facing: np.ndarray | None = None, partial: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detections of the robot-frame positions ``xy`` (n, 2) that are ``visible``: each missed with probability
    ``miss_prob``, the rest moved by range noise ``laser_std_m`` within ``laser_reach_m``, else ``range_std_m +
    range_std_per_m * r``, and bearing noise
    ``bearing_std_deg`` (Gaussian). ``facing`` (n,): each person's true facing relative to their line of sight
    (rad, 0: looking at the robot), measured with ``facing_std_deg`` within ``facing_front_deg`` of 0, else with
    ``facing_back_std_deg`` (NaN where that is inf), turned by 180 deg with probability ``facing_flip_prob``.
    ``partial`` (n,): completed beyond the image's side, with
    ``partial_std_m`` more noise across the line of sight.
    Returns the detections (k, 2), their measured facing (k,) and its std (k,) (NaN/inf: unknown). Draws the same
    numbers whatever is visible (one miss, range, bearing and facing draw per person), so one person's visibility
    does not change another's noise."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    n = len(xy)
    miss = rng.random(n) < params.miss_prob
    z_range, z_bearing, z_facing = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    z_across = rng.standard_normal(n)
    r = np.hypot(xy[:, 0], xy[:, 1])
    b = np.arctan2(xy[:, 1], xy[:, 0])
    across = 0.0 if partial is None else np.where(partial, params.partial_std_m, 0.0) / np.maximum(r, 0.1)
    sd_range = np.where(r < params.laser_reach_m, params.laser_std_m, params.range_std_m + params.range_std_per_m * r)
    r = np.maximum(r + sd_range * z_range, 0.05)
    b = b + math.radians(params.bearing_std_deg) * z_bearing + across * z_across
    phi = np.full(n, np.nan) if facing is None else np.asarray(facing, dtype=float)
    front = np.abs(np.remainder(phi + math.pi, 2 * math.pi) - math.pi) <= math.radians(params.facing_front_deg)
    sd = np.where(front, max(math.radians(params.facing_std_deg), 1e-3),
                  max(math.radians(params.facing_back_std_deg), 1e-3))
    known = np.isfinite(phi) & np.isfinite(sd)
    if params.facing_flip_prob > 0:  # drawn only then: the colour chain's draws stay as they were
        phi = phi + math.pi * (rng.random(n) < params.facing_flip_prob)
    measured = np.where(known, phi + np.where(known, sd, 0.0) * z_facing, np.nan)
    std = np.where(known, sd, np.inf)
    keep = np.asarray(visible, dtype=bool) & ~miss
    return np.column_stack([r * np.cos(b), r * np.sin(b)])[keep], measured[keep], std[keep]


# (share of ``sidestep_s``, share of ``sidestep_clearance``) tried in turn where walls or furniture leave no room
# for the whole step: in a map room, a robot whose 0.8 m step had no room either side turned on the spot for the
# whole episode, one member hidden behind the other (small room, 13 % of 200 starts); the last keeps the clearance
# at which a step under way stops
SIDESTEP_SHARES = ((1.0, 1.0), (2 / 3, 1.0), (1 / 3, 0.5))
# ... and directions (rad from the line to the person, left positive): across it, else across and back (never
# toward the person)
SIDESTEP_ANGLES = (math.pi / 2, 3 * math.pi / 4)


class CopyPerception:
    """One copy's pipeline: its generator, deploy's tracker with its memory, and deploy's group model."""

    def __init__(self, robot: RobotParams, social: SocialParams, keep: float, paper: bool,
                 params: PerceptionParams) -> None:
        self.torso_halfwidth = TORSO_HALF[1]
        self.apparent_halfwidth = 2.0 * sum(TORSO_HALF) / math.pi  # the mean over facings
        self.body_height = BODY_HEIGHT  # deploy's: the torso's middle
        self.params, self.paper = params, paper
        keypoints = params.keypoints  # deploy's tracker, memory and centre for the chain (``deploy.perceive``)
        self.model = GroupModel(social, keep, paper=paper, robust=keypoints and not paper)
        self.tracker = GroupTracker(sim_camera(robot, *IMAGE_SIZE), TRACKER_KEYPOINTS if keypoints else TRACKER,
                                    KEYPOINT_GROUP if keypoints else GroupParams(), social=social, model=self.model)
        self.margin = self.tracker.p.edge_margin_m  # m beyond the torso that must be in the image too
        self.rng = np.random.default_rng()
        self.approaching = False
        self.search_side = 0.0
        self.turned, self.last_yaw, self.sidestep_left = 0.0, None, 0  # the search's progress
        self.sidestep_angle, self.sidesteps = math.pi / 2, 0  # the sidestep's direction, sidesteps in a row
        self.members: list[Any] = []
        self.group: tuple[np.ndarray, float, float, np.ndarray] | None = None  # centre, radius, joining, slot
        self.looks, self.t = Looks(params.confirm_s), 0.0  # deploy's looks, on the episode's clock (s)

    def seed(self, seed: int | None) -> None:
        self.rng = np.random.default_rng(None if seed is None else [int(seed), 37])

    def reset(self) -> None:
        """A new episode: nothing known (the generator goes on)."""
        self.tracker.tracker.reset()
        self.tracker.members.clear()
        self.model.reset()
        self.approaching, self.search_side, self.members, self.group = False, 0.0, [], None
        self.turned, self.last_yaw, self.sidestep_left, self.sidesteps = 0.0, None, 0, 0
        self.looks, self.t = Looks(self.params.confirm_s), 0.0

    def detectable(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Which robot-frame people (n, 2) the detector can find (enough of the torso, plus the chain's edge margin,
        inside the image, not too much hidden behind nearer people; or cut by the image's side and placed by a laser,
        ``cut_share``), the share of each inside the image, and which are found cut."""
        p = self.params
        share = image_share(xy, self.tracker.camera, self.apparent_halfwidth + self.margin, self.body_height,
                            self.tracker.p.max_range_m)
        clear = hidden_share(xy, self.torso_halfwidth) <= p.hidden_fraction
        whole = (share >= p.min_visible - 1e-9) & clear
        cut = np.zeros(len(whole), dtype=bool)
        if p.cut_share > 0:
            cut = ~whole & clear & (share >= p.cut_share) & (np.hypot(xy[:, 0], xy[:, 1]) < p.laser_reach_m) \
                & lasers_see_body(xy, self.torso_halfwidth)
        return whole | cut, share, cut

    def frame(self, pose: np.ndarray, members: np.ndarray, dt: float, yaw: np.ndarray | None = None) -> None:
        """One camera frame at the robot's ``pose`` (room frame, used as the odometry frame) with the true
        ``members`` (n, 2) facing ``yaw`` (n,; None: facing unknown): detect, track, and, with two or more people
        known, the group as deploy's loop computes it (a new approach resets the model, as ``DeployLoop._act``
        does)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rel = np.asarray(members, dtype=float).reshape(-1, 2) - pose[:2]
        xy = np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]])
        can, share, cut = self.detectable(xy)
        phi = None
        if yaw is not None:  # facing relative to the line of sight: 0 when looking at the robot; unknown when cut
            phi = np.where(cut, np.nan, np.asarray(yaw, dtype=float) - np.arctan2(-rel[:, 1], -rel[:, 0]))
        seen, facing, std = detect(xy, can, self.params, self.rng, phi, share < 1.0)
        self.members = self.tracker.update(seen, dt, np.asarray(pose, dtype=float), facing, std)
        self.t += dt
        self.looks.saw(self.members, self.t)
        if len(self.members) < 2:
            self.approaching, self.group = False, None
            return
        if not self.approaching:
            self.model.reset()
            self.looks.new_approach()
            self.approaching, self.search_side = True, 0.0  # the next search starts afresh
        pos, rest, facing, facing_std = member_arrays(self.members)
        self.group = self.model.update(pos, np.asarray(pose[:2], dtype=float), rest, facing, facing_std)

    def look(self, pose: np.ndarray, speed: float, task: Any) -> int | None:
        """The member (index into ``members``) deploy's loop would turn toward now, as ``DeployLoop.tick`` asks
        ``looks``: before a claim on the estimated group (``looks.claim_rule``), or stalled away from its place;
        None when the policy drives. Call once per step, after ``frame``, with the group known."""
        centre, _, _, slot = self.group
        slot_distance = float(np.hypot(*(slot - pose[:2])))
        heading = math.remainder(math.atan2(centre[1] - pose[1], centre[0] - pose[0]) - pose[2], 2 * math.pi)
        success = claim_rule(slot_distance, speed, heading, task)
        return self.looks.decide(self.members, self.t, success, slot_distance, speed, task)[2]

    def search(self, pose: np.ndarray, heading_gain: float, dt: float,
               clearance: Callable[[np.ndarray], float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Deploy's search (``DeployLoop._search``) as the engine's aim and body action: turn in place at
        ``search_turn`` rad/s under the env's proportional heading control, toward the one known person's side
        first; after a full turn with still one person known, ``sidestep_s`` sideways at ``sidestep_speed``
        (``sidestep_repeats`` times in a row while that person stays the only one)
        facing that person, to whichever side keeps ``sidestep_clearance`` from walls and furniture all the way
        (``clearance``: the footprint's static clearance at a pose), or a shorter step (``SIDESTEP_SHARES``) where
        neither side has room for the whole one, or across and back (``SIDESTEP_ANGLES``); none free: it keeps
        turning. Returns the aim
        (2,) and the action's (forward, left) in m/s."""
        p = self.params
        if self.search_side == 0.0:  # a new search
            side = 1.0
            if self.members:
                d = self.members[0].pos - pose[:2]
                side = 1.0 if math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi) >= 0 else -1.0
            self.search_side, self.turned, self.last_yaw, self.sidestep_left, self.sidesteps = side, 0.0, None, 0, 0
        if self.last_yaw is not None:
            self.turned += abs(math.remainder(pose[2] - self.last_yaw, 2 * math.pi))
        self.last_yaw = float(pose[2])
        one = len(self.members) == 1
        if one:  # a sidestep moves across the line to that person: the action's frame faces them
            d = self.members[0].pos - pose[:2]
            toward = d / max(float(np.hypot(*d)), 1e-6)
            across = np.array([-toward[1], toward[0]])

            def free_at(angle: float, length: float) -> float:
                q = np.asarray(pose[:2], dtype=float) + length * (math.cos(angle) * toward + math.sin(angle) * across)
                return clearance(np.array([q[0], q[1], pose[2]])) if clearance is not None else math.inf
        again = self.sidestep_left == 0 and 0 < self.sidesteps < p.sidestep_repeats
        if one and (self.turned >= 2 * math.pi or again):  # the whole step where there is room, else a shorter one
            self.turned, self.sidestep_left, self.sidesteps = 0.0, 0, self.sidesteps + 1 if again else 1
            tries = [(share, room, side * angle) for share, room in SIDESTEP_SHARES for angle in SIDESTEP_ANGLES
                     for side in (self.search_side, -self.search_side)]
            for share, room, angle in tries:
                step = share * p.sidestep_s * p.sidestep_speed + 0.2  # the step and the base's braking
                if free_at(angle, step) >= room * p.sidestep_clearance:
                    self.search_side = 1.0 if angle > 0 else -1.0
                    self.sidestep_angle, self.sidestep_left = angle, int(round(share * p.sidestep_s / dt))
                    break
        if self.sidestep_left > 0 and one and free_at(self.sidestep_angle, 0.3) < p.sidestep_clearance / 2:
            self.sidestep_left = 0  # it turns as it goes: what is across changes; looked at again each step
        if self.sidestep_left > 0 and one:
            self.sidestep_left -= 1
            a = self.sidestep_angle
            return self.members[0].pos.copy(), p.sidestep_speed * np.array([math.cos(a), math.sin(a)])
        turn = self.search_side * p.search_turn / heading_gain
        aim = np.asarray(pose[:2], dtype=float) + np.array([math.cos(pose[2] + turn), math.sin(pose[2] + turn)])
        return aim, np.zeros(2)


class PerceivedGroups:
    """N copies' perceived groups in the engine's array layout (``core.humans.GroupArrays``' ``count``, ``pos``,
    ``vel``, ``centre``, ``scalars[:, RADIUS]``, and the slot), which ``env.engine.kernels.observations`` turns into the
    Vector observation in place of the true ones; ``known``: two or more people known (else the robot
    searches, and the observation's group is empty: its centre just ahead of the robot, its place at it)."""

    def __init__(self, num: int, robot: RobotParams, social: SocialParams, keep: float, paper: bool,
                 params: PerceptionParams) -> None:
        self.params = params
        self.copies = [CopyPerception(robot, social, keep, paper, params) for _ in range(num)]
        self.count = np.zeros(num, dtype=np.int64)
        self.pos = np.zeros((num, MAX_HUMANS, 2))
        self.vel = np.zeros((num, MAX_HUMANS, 2))
        self.centre = np.zeros((num, 2))
        self.scalars = np.zeros((num, N_SCALARS))
        self.slot = np.zeros((num, 2))
        self.known = np.zeros(num, dtype=bool)

    @property
    def oracle_columns(self) -> list[slice]:
        """The observation's columns the engine takes from the true state (``PerceptionParams.oracle``)."""
        return [ORACLE_COLUMNS[part] for part in self.params.oracle]

    def seed(self, i: int, seed: int | None) -> None:
        self.copies[i].seed(seed)

    def reset(self, i: int, pose: np.ndarray, members: np.ndarray, yaw: np.ndarray, dt: float) -> None:
        """Copy ``i``'s new episode and its first frame."""
        self.copies[i].reset()
        self.frame(i, pose, members, yaw, dt)

    def frame(self, i: int, pose: np.ndarray, members: np.ndarray, yaw: np.ndarray, dt: float) -> None:
        """Copy ``i``'s frame after a step (the true members (n, 2) facing ``yaw`` (n,)), into the arrays."""
        cp = self.copies[i]
        cp.frame(pose, members, dt, yaw)
        people = cp.members
        if cp.group is not None and len(people) > MAX_HUMANS:  # the observation holds the nearest few anyway
            d = [float(np.hypot(*(m.pos - cp.group[0]))) for m in people]
            people = [people[k] for k in np.argsort(d, kind="stable")[:MAX_HUMANS]]
        n = min(len(people), MAX_HUMANS)
        self.count[i] = n
        self.pos[i], self.vel[i] = 0.0, 0.0
        for k, m in enumerate(people[:n]):
            self.pos[i, k], self.vel[i, k] = m.pos, m.vel
        self.known[i] = cp.group is not None
        if cp.group is not None:
            centre, radius, _, slot = cp.group
            self.centre[i], self.scalars[i, RADIUS], self.slot[i] = centre, radius, slot
        else:
            ahead = np.array([math.cos(pose[2]), math.sin(pose[2])])
            self.centre[i], self.scalars[i, RADIUS], self.slot[i] = pose[:2] + 1e-3 * ahead, 0.0, pose[:2]

    def steer(self, pose: np.ndarray, heading_gain: float, dt: float,
              clearance: Callable[[int, np.ndarray], float] | None = None, speed: np.ndarray | None = None,
              task: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 2) each robot's aim (``kernels.step``: the perceived centre, or its search's or look's), (N, 2) the
        body action (forward, left; m/s) of the copies deploy would drive itself, and (N,) which of those copies
        know the group and look at a member (``CopyPerception.look``; needs ``speed`` (N,), the robots' planar
        speeds, and ``task``, the success rule; the others search); ``clearance(i, pose)``: copy i's footprint's
        static clearance at a pose (for the sidestep). A look turns in place, at most ``search_turn`` rad/s under
        the env's proportional heading control, as ``DeployLoop._turn_to``."""
        aim, act = self.centre.copy(), np.zeros((len(self.known), 2))
        for i in np.flatnonzero(~self.known).tolist():
            free = None if clearance is None else (lambda q, i=i: clearance(i, q))
            aim[i], act[i] = self.copies[i].search(pose[i], heading_gain, dt, free)
        looking = np.zeros(len(self.known), dtype=bool)
        if speed is None or task is None:
            return aim, act, looking
        for i in np.flatnonzero(self.known).tolist():
            cp = self.copies[i]
            k = cp.look(pose[i], float(speed[i]), task)
            if k is None:
                continue
            d = cp.members[k].pos - pose[i, :2]
            heading = math.remainder(math.atan2(d[1], d[0]) - pose[i, 2], 2 * math.pi)
            turn = min(max(heading_gain * heading, -self.params.search_turn), self.params.search_turn) / heading_gain
            aim[i] = pose[i, :2] + np.array([math.cos(pose[i, 2] + turn), math.sin(pose[i, 2] + turn)])
            looking[i] = True
        return aim, act, looking
