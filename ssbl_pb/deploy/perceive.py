"""Camera frames to tracked people, off the control tick: a grabber keeps the newest frame, a detector worker
runs detector -> ground-plane projection -> tracker (ego-motion compensated) on the newest frame it has not
seen. A slow detector ages the estimate; it never delays a command. In lockstep (tests) both run inline.

Times: frames carry the robot's clock; the local capture time is ``stamp + offset`` with ``offset`` the
smallest (receive time - stamp) seen so far, so a frozen camera (time stamps that stop changing) ages the
newest frame even though frames keep arriving.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import threading
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from ..errors import UserError
from ..params import RobotParams, SocialParams
from ..perception.camera import PinholeCamera, sim_camera
from ..perception.detection.detectors import ColourDetector, HogDetector, HogParams
from ..perception.detection.facing import Facing, facing_yaw
from ..perception.detection.ground import ProxyGeometry, boxes_to_ground
from ..perception.detection.keypoint_range import BODY_MARGIN
from ..perception.detection.laser_range import LEG_DEPTH_M, laser_ranged
from ..perception.detection.learned import SsdDetector
from ..perception.detection.movenet import MoveNetFacing
from ..perception.detection.proxy_facing import estimate_facing
from ..perception.groups.estimate import (
    KEYPOINT_GROUP,
    MIN_VISIBLE,
    TORSO_HALF,
    TORSO_HEIGHT,
    TRACKER,
    TRACKER_KEYPOINTS,
    GroupParams,
    GroupTracker,
    Member,
)
from ..perception.tracking.tracker import TrackerParams
from ..urdf import HUMAN_COLOURS
from .robot import Frame, Robot

DETECTORS = ("colour", "hog", "ssd", "movenet")


def torso_depth(xy: np.ndarray, centre: np.ndarray | None) -> np.ndarray:
    """How far in front of the body's axis, along the line of sight, the ground points (robot frame, (n, 2)) of
    torso boxes lie. A box's top and bottom edges are those of the torso's corner nearest the camera (the torso
    spans the camera's height), a|cos phi| + b|sin phi| in front of the axis when the person's facing makes an
    angle phi with the line of sight (a, b: ``TORSO_HALF``). People in a group face its centre (``centre``, robot
    frame; core.humans); without one, the mean over phi, 2 (a + b) / pi. Measured on the virtual Pepper (seeded
    lockstep runs, bodies 1-2.5 m away seen side-on at the group): with one constant (0.18 m) the estimates fell
    0.07 m short, which the policy's clearance to the members (0.52-0.6 m true) cannot spare against the 0.45 m
    stop distance."""
    a, b = TORSO_HALF
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if centre is None:
        return np.full(len(xy), 2.0 * (a + b) / math.pi)
    u = xy / np.maximum(np.hypot(xy[:, 0], xy[:, 1]), 1e-6)[:, None]  # from the camera toward the person
    f = np.asarray(centre, dtype=float) - xy
    f = f / np.maximum(np.hypot(f[:, 0], f[:, 1]), 1e-6)[:, None]  # the person's facing
    cos = np.clip(-(f * u).sum(axis=1), -1.0, 1.0)
    return a * np.abs(cos) + b * np.sqrt(1.0 - cos * cos)


def one_per_colour(palette: list[Any]) -> Callable[[np.ndarray], np.ndarray]:
    """The colour detector with one box per colour, the union of that colour's blobs: each simulated person wears
    their own colour (``world.HUMAN_COLOURS``), and one standing behind a nearer person shows a sliver of their
    torso on either side of that person, which made two detections, hence two tracks, of one person (virtual
    Pepper, lockstep ``mixed`` runs). The union spans the torso's hidden middle, so its centre is the torso's."""

    class OnePerColour(ColourDetector):
        last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # frame, hsv, boxes, colours

        def __call__(self, frame: np.ndarray) -> np.ndarray:
            p = self.params
            hsv = cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2HSV)
            sat = (hsv[..., 1] >= p.min_saturation) & (hsv[..., 2] >= p.min_value)
            hue = hsv[..., 0].astype(int)
            out, colours = [], []
            for c, h0 in enumerate(self.hues):
                d = np.abs(hue - h0)
                blobs: list = []
                self._blobs(sat & (np.minimum(d, 180 - d) <= p.hue_tol), blobs)
                if blobs:
                    b = np.array(blobs, dtype=float)
                    x0, y0 = b[:, 0].min(), b[:, 1].min()
                    out.append([x0, y0, (b[:, 0] + b[:, 2]).max() - x0, (b[:, 1] + b[:, 3]).max() - y0, b[:, 4].max()])
                    colours.append(c)
            boxes = np.array(out, dtype=float).reshape(-1, 5)
            self.last = (frame, hsv, boxes, np.array(colours, dtype=int))
            return boxes

        @property
        def last_colours(self) -> np.ndarray:
            """The palette index of each box of the last frame."""
            return self.last[3] if self.last is not None else np.zeros(0, dtype=int)

        def facing(self, camera: PinholeCamera | None = None) -> Facing:
            """Facing of each box of the last frame (rows as that call returned them: index them as its boxes;
            ``perception.detection.proxy_facing.estimate_facing``). ``camera``: the frame's, default the simulated
            CameraTop."""
            if self.last is None:
                raise RuntimeError("facing: no frame detected yet")
            frame, hsv, boxes, colours = self.last
            return estimate_facing(frame, boxes, camera, colours=colours, palette=palette, hsv=hsv,
                                   colour_params=self.params)

    return OnePerColour(palette)




def complete_cut_torsos(boxes: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Torso boxes cut by the image's side, completed beyond it: the box's inner edge is the torso's, its height
    (the torso's 0.60 m, whole: the camera sees its top and bottom) gives the torso's apparent width, the mean
    over facings of 2 (a |sin phi| + b |cos phi|) = 4 (a + b) / pi (``TORSO_HALF``; off by at most 0.07 m either
    side). Returns the boxes and which count: whole ones, and cut ones showing at least ``MIN_VISIBLE`` of their
    width. Near the group, members 20-45 deg to the side are cut by the image's side; dropped, they were never
    detected and the robot came into their intimate zone (4-5 % of `mixed` starts with the observation model)."""
    b = np.array(boxes, dtype=float, copy=True)
    left, right = b[:, 0] <= 1, b[:, 0] + b[:, 2] >= width - 1
    full = b[:, 3] * (4.0 * sum(TORSO_HALF) / math.pi) / TORSO_HEIGHT
    cut = left ^ right  # cut on both sides: too close to tell
    keep = (~left & ~right) | (cut & (b[:, 2] >= MIN_VISIBLE * full))
    grow = cut & (b[:, 2] < full)
    b[grow & left, 0] = b[grow & left, 0] + b[grow & left, 2] - full[grow & left]
    b[grow, 2] = full[grow]
    return b, keep


def whole_people(boxes: np.ndarray, width: int, margin: float = 0.0) -> np.ndarray:
    """Which person boxes (``x, y, w, h``, ...) show the whole body across: more than a pixel plus ``margin`` times
    their height clear of either side of an image ``width`` px wide (``BODY_MARGIN`` for MoveNet's keypoint boxes)."""
    b = np.asarray(boxes, dtype=float).reshape(len(boxes), -1) if len(boxes) else np.zeros((0, 4))
    clear = 1.0 + margin * b[:, 3]
    return (b[:, 0] > clear) & (b[:, 0] + b[:, 2] < width - clear)


def make_detector(name: str) -> tuple[Callable[[np.ndarray], np.ndarray], bool]:
    """A detector for RGB frames and whether its boxes are torsos (``colour``: the simulated people's
    saturated torsos, for the virtual Pepper) or whole people (``hog``: OpenCV's people detector; ``ssd``: the
    learned SSDLite pedestrian detector, ``perception.detection.learned``; ``movenet``: MoveNet MultiPose,
    ``perception.detection.movenet``, the default on a real robot; the learned ones' boxes may end above the feet:
    those are ranged from the head by ``boxes_to_ground``, MoveNet's from its keypoints by ``detector.ground()``).
    The colour detector and MoveNet also tell each box's facing: after a call, ``detector.facing()``
    (``one_per_colour``, ``movenet.MoveNetFacing``)."""
    if name == "colour":
        return one_per_colour(HUMAN_COLOURS), True
    if name == "hog":
        # Pepper's QVGA frames show a standing person 2-5 m away 100-250 px tall: downscales fit the 128 px window
        hog = HogDetector(HogParams(scales=(0.5, 0.7, 1.0)))
        return (lambda rgb: hog(np.ascontiguousarray(rgb[..., ::-1]))), False
    if name in ("ssd", "movenet"):
        # lazy: optional, the PETS-tuned settings' module needs motmetrics (the tracking extra)
        from ..perception.tracking.tuning import MOVENET_DEFAULT, SSD_DEFAULT
    if name == "ssd":
        # thresholds as chosen on PETS, without its minimum height (people near the robot are large)
        return SsdDetector(dataclasses.replace(SSD_DEFAULT.ssd, min_height=0.0), rgb=True), False
    if name == "movenet":
        # positions and facing from the keypoints too (``ground``, ``facing``)
        return MoveNetFacing(dataclasses.replace(MOVENET_DEFAULT.ssd, min_height=0.0), MOVENET_DEFAULT.rng), False
    raise UserError(f"--detector {name!r}: expected one of {list(DETECTORS)}")


def pose_at(history: collections.deque, t: float) -> np.ndarray:
    """Odometry pose at local time ``t``, interpolated in ``history`` ((time, pose) pairs, oldest first)."""
    items = list(history)
    if not items:
        raise ValueError("pose_at: no odometry yet")
    if t <= items[0][0]:
        return items[0][1]
    for (t0, p0), (t1, p1) in zip(items, items[1:], strict=False):
        if t0 <= t <= t1:
            w = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
            yaw = p0[2] + w * math.remainder(p1[2] - p0[2], 2 * math.pi)
            return np.array([p0[0] + w * (p1[0] - p0[0]), p0[1] + w * (p1[1] - p0[1]), yaw])
    return items[-1][1]


def detector_for(name: str, robot: Any) -> str:
    """``--detector auto``: on a virtual Pepper the detector it names over qi (MoveNet for its bodies, colour for its
    box proxies), MoveNet on a real one (the detector that meets the PETS targets with the feet in view and hidden,
    docs/tracking.md)."""
    if name != "auto":
        return name
    identity = getattr(robot, "identity", None)
    return str(identity.get("detector", "colour")) if identity else "movenet"


def _depth(value: object) -> float:
    """The robot's ``person_laser_depth_m`` (m, 0-1), or a ``UserError`` naming it."""
    try:
        depth = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        depth = math.nan
    if not 0.0 <= depth <= 1.0:
        raise UserError(f"robot identity: person_laser_depth_m = {value!r}: expected metres in [0, 1] (from a "
                        f"laser's return to a person's centre)")
    return depth


@dataclasses.dataclass
class Estimate:
    """Members (odometry frame) from the frame captured at local time ``capture``; ``detections`` in it."""

    members: list[Member]
    capture: float
    detections: int


class Perception:
    """Grabber + detector worker; ``latest`` is the newest estimate, ``capture`` the newest frame's time."""

    def __init__(self, robot: Robot, now: Callable[[], float], detector: str = "colour",
                 robot_params: RobotParams | None = None, camera: PinholeCamera | None = None,
                 tracker: TrackerParams | None = None, social: SocialParams | None = None, threaded: bool = True,
                 poll_s: float = 0.02) -> None:
        """``camera``: a calibrated camera (rescaled to the frames); default Pepper's nominal CameraTop."""
        self.robot, self.now, self.threaded, self.poll_s = robot, now, threaded, poll_s
        self.detect, self.torso = make_detector(detector)
        self.robot_params = robot_params or RobotParams()
        self.calibrated = camera
        self.tracker_params = tracker
        self.social = social or SocialParams()
        self.centre0: np.ndarray | None = None  # set by the loop: the group's centre before joining (odometry)
        self.group_model: Any = None  # set by the loop: its ``group.GroupModel`` (its joining weight marks rests)
        identity = getattr(robot, "identity", None) or {}
        # from a laser's return to the person's centre: a real Pepper's lasers hit feet and shins; the virtual
        # Pepper says what its lasers hit
        self.laser_depth = _depth(identity.get("person_laser_depth_m", LEG_DEPTH_M))
        self.scan: np.ndarray | None = None  # the lasers' last returns, odometry frame (``ranges``; None: none)
        self.odometry: collections.deque = collections.deque(maxlen=200)  # (local time, pose), from the loop
        self.offset = math.inf
        self.newest: Frame | None = None
        self.capture = -math.inf  # local capture time of the newest frame
        self.latest: Estimate | None = None
        self.error: BaseException | None = None
        self._group: GroupTracker | None = None
        self._done: float | None = None  # stamp of the last processed frame
        self._lock = threading.Lock()
        self._new = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def ranges(self, points: np.ndarray, pose: np.ndarray) -> None:
        """The lasers' returns (robot frame at odometry ``pose``; sonar echoes left out), from the control loop:
        the detector's people are ranged by them (``laser_ranged``), where it tells no torso."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        pts = np.asarray(points, dtype=float).reshape(-1, 2) @ np.array([[c, s], [-s, c]]) + pose[:2]
        with self._lock:
            self.scan = pts

    # -- the two jobs ----------------------------------------------------------------------------------------
    def grab(self) -> bool:
        """Fetch the robot's newest frame; True when it is new."""
        frame = self.robot.frame()
        if frame is None:
            return False
        with self._lock:
            if self.newest is not None and frame.stamp == self.newest.stamp:
                return False
            self.offset = min(self.offset, self.now() - frame.stamp)
            self.newest, self.capture = frame, frame.stamp + self.offset
            self._new.notify_all()
        return True

    def process(self) -> bool:
        """Detect and track on the newest frame if it has not been processed; True when it was."""
        with self._lock:
            frame, capture = self.newest, self.capture
            if frame is None or frame.stamp == self._done or not self.odometry:
                return False
            pose = pose_at(self.odometry, capture)
        prev, self._done = self._done, frame.stamp
        h, w = frame.image.shape[:2]
        if self._group is None or self._group.camera.width != w:
            cam = self.calibrated.scaled(w, h) if self.calibrated is not None else sim_camera(self.robot_params, w, h)
            keypoints = isinstance(self.detect, MoveNetFacing)
            params = self.tracker_params or (TRACKER_KEYPOINTS if keypoints else TRACKER)
            group = KEYPOINT_GROUP if keypoints else GroupParams()
            self._group = GroupTracker(cam, params, group, social=self.social, model=self.group_model)
        boxes = self.detect(frame.image)
        # each person's facing, where the detector tells it (the virtual Pepper's colour detector, MoveNet's
        # keypoints), from every box:
        # a person cut by the image's side still hides part of whoever stands behind them
        seen = self.detect.facing(self._group.camera) if hasattr(self.detect, "facing") else None
        # a box cut by the image's side: a torso completed beyond the side (``complete_cut_torsos``), a whole person
        # (HOG) is off by up to half a body and dropped, MoveNet's too near the side (``whole_people``) unless a
        # laser places them (below)
        keypoints = isinstance(self.detect, MoveNetFacing)
        margin = BODY_MARGIN if keypoints else 0.0
        boxes, whole = complete_cut_torsos(boxes, w) if self.torso else (boxes, whole_people(boxes, w, margin))
        cut = ~whole if keypoints else np.zeros(len(boxes), dtype=bool)
        whole = whole | cut
        boxes = boxes[whole]
        if self.torso:  # the torso's edges are the outer edges of the box's first and last rows, not their centres
            boxes = boxes.copy()  # (half a pixel: 0.1 m of range 5 m away; boxes_to_ground takes pixel centres)
            boxes[:, 1] -= 0.5
            boxes[:, 3] += 1.0
        if hasattr(self.detect, "ground"):  # MoveNet: the feet, else the keypoints (``MoveNetFacing.ground``)
            xy = self.detect.ground(self._group.camera)[whole]
        else:
            xy = boxes_to_ground(self._group.camera, boxes, ProxyGeometry(), torso=self.torso)
        found = np.isfinite(xy[:, 0])
        with self._lock:
            scan = self.scan
        ranged = np.zeros(len(xy), dtype=bool)
        if not self.torso and scan is not None:  # to the robot frame at capture
            c, sn = math.cos(pose[2]), math.sin(pose[2])
            lasers = (scan - pose[:2]) @ np.array([[c, -sn], [sn, c]])
            xy[found], ranged[found] = laser_ranged(xy[found], lasers, self.laser_depth)
        # a person the image's side cuts: kept where a laser places them (their returns' range and bearing; the
        # keypoints of half a body tell neither, nor the facing), else dropped
        cut = cut[whole]
        found &= ~cut | ranged
        xy, cut = xy[found], cut[found]
        if self.torso and len(xy):
            centre = None
            if self.centre0 is not None:  # the group's centre in the robot frame at capture
                c, sn = math.cos(pose[2]), math.sin(pose[2])
                d = np.asarray(self.centre0, dtype=float) - pose[:2]
                centre = np.array([c * d[0] + sn * d[1], -sn * d[0] + c * d[1]])
            rng = np.hypot(xy[:, 0], xy[:, 1])[:, None]
            xy = xy * (1.0 + torso_depth(xy, centre)[:, None] / np.maximum(rng, 1e-6))
        dt = frame.stamp - prev if prev is not None and 0 < frame.stamp - prev < 1.0 else 0.1
        facing = facing_std = None
        if seen is not None:  # phi relative to the line of sight from the robot's origin, as the tracker takes it
            phi, std = np.where(cut, np.nan, seen.phi[whole][found]), seen.std[whole][found]
            yaw = facing_yaw(xy, np.nan_to_num(phi), self._group.camera.centre()[:2])
            facing = np.where(np.isfinite(phi), yaw - np.arctan2(-xy[:, 1], -xy[:, 0]), np.nan)
            facing_std = np.where(np.isfinite(phi), std, np.inf)
        members = self._group.update(xy, dt, pose, facing, facing_std)
        est = Estimate([dataclasses.replace(m) for m in members], capture, len(xy))
        with self._lock:
            self.latest = est
        return True

    # -- running them ----------------------------------------------------------------------------------------
    def _run(self, job: Callable[[], bool], wait: Callable[[], None]) -> None:
        try:
            while not self._stop.is_set():
                if not job():
                    wait()
        except BaseException as exc:  # handed to the control loop, which stops the base and re-raises it
            self.error = exc

    def _wait_new(self) -> None:
        with self._lock:
            self._new.wait(self.poll_s)

    def start(self) -> None:
        if not self.threaded:
            return
        for name, job, wait in (("grab", self.grab, lambda: self._stop.wait(self.poll_s)),
                                ("detect", self.process, self._wait_new)):
            th = threading.Thread(target=self._run, args=(job, wait), name=f"deploy-{name}", daemon=True)
            th.start()
            self._threads.append(th)

    def step(self) -> None:
        """Inline mode: grab and process once (the loop calls this each tick)."""
        if not self.threaded:
            self.grab()
            self.process()

    def check(self) -> None:
        """Re-raise a worker's exception in the caller (the control loop)."""
        if self.error is not None:
            raise self.error

    def stop(self, timeout_s: float = 0.2) -> None:
        self._stop.set()
        with self._lock:
            self._new.notify_all()
        for th in self._threads:
            th.join(timeout_s)

    def snapshot(self) -> tuple[Estimate | None, float]:
        with self._lock:
            return self.latest, self.capture

    def info(self) -> dict[str, Any]:
        return {"offset_s": self.offset, "torso_boxes": self.torso}
