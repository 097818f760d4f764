"""Ground-truth boxes: the CVML XML of the PETS 2009 annotations, and MOTChallenge text files.

Both load to one array layout, ``(n, 7)`` rows of ``frame (0-based), id, left, top, w, h, score``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from .xmlfile import xml_root

CVML_EXPECTED = "CVML XML: <dataset><frame number><objectlist><object id><box h w xc yc/>"
MOT_EXPECTED = "MOTChallenge text: frame(1-based),id,left,top,w,h,score,..."


class GroundTruthError(UserError):
    """A ground-truth or track file is missing or in another format; the message names file and format."""


def load_cvml(path: str | Path) -> np.ndarray:
    """PETS CVML XML -> ``(n, 7)`` array ``frame, id, left, top, w, h, 1`` (frame numbers as in the file)."""
    path = Path(path)
    root = xml_root(path, GroundTruthError, CVML_EXPECTED, "ground-truth file")
    frames = root.findall("frame")
    if root.tag != "dataset" or not frames:
        raise GroundTruthError(f"{path}: root <{root.tag}> has no <frame> children; expected {CVML_EXPECTED}")
    rows = []
    for fr in frames:
        try:
            num = int(fr.get("number", ""))
            for obj in fr.iterfind("objectlist/object"):
                box = obj.find("box")
                if box is None:
                    raise GroundTruthError(f"{path}: frame {num} object {obj.get('id')} has no <box>; "
                                           f"expected {CVML_EXPECTED}")
                h, w = float(box.get("h", "")), float(box.get("w", ""))
                xc, yc = float(box.get("xc", "")), float(box.get("yc", ""))
                rows.append((num, int(obj.get("id", "")), xc - w / 2, yc - h / 2, w, h, 1.0))
        except ValueError as exc:
            if isinstance(exc, GroundTruthError):
                raise
            raise GroundTruthError(f"{path}: frame {fr.get('number')!r}: missing or non-numeric attribute "
                                   f"({exc}); expected {CVML_EXPECTED}") from exc
    return np.array(rows, dtype=float).reshape(-1, 7)


def load_mot(path: str | Path) -> np.ndarray:
    """MOTChallenge text -> ``(n, 7)`` array with 0-based frames."""
    path = Path(path)
    if not path.is_file():
        raise GroundTruthError(f"{path}: file not found; expected {MOT_EXPECTED}")
    try:
        data = np.loadtxt(path, delimiter=",", ndmin=2)
    except ValueError as exc:
        raise GroundTruthError(f"{path}: cannot parse ({exc}); expected {MOT_EXPECTED}") from exc
    if data.size == 0:
        return np.zeros((0, 7))
    if data.shape[1] < 6:
        raise GroundTruthError(f"{path}: {data.shape[1]} columns; expected {MOT_EXPECTED}")
    score = data[:, 6] if data.shape[1] > 6 else np.ones(len(data))
    out = np.column_stack([data[:, 0] - 1, data[:, 1:6], score])
    return out


def load_ground_truth(path: str | Path) -> np.ndarray:
    """Load GT by extension: ``.xml`` -> CVML, ``.txt`` -> MOTChallenge; anything else is an error."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".xml":
        return load_cvml(path)
    if suffix == ".txt":
        return load_mot(path)
    raise GroundTruthError(f"{path}: unknown ground-truth format {suffix!r}; expected {CVML_EXPECTED} (.xml) "
                           f"or {MOT_EXPECTED} (.txt)")


def foot_points(boxes: np.ndarray) -> np.ndarray:
    """Bottom-centre pixel of ``left, top, w, h`` boxes (..., 4) -> (..., 2)."""
    boxes = np.asarray(boxes, dtype=float)
    return np.stack([boxes[..., 0] + boxes[..., 2] / 2, boxes[..., 1] + boxes[..., 3]], axis=-1)
