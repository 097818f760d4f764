"""Real conversational groups (F-formations) from the GCFF ``.mat`` files (shared/data/fformations/SOURCES.md).

A dataset folder holds ``features.mat`` (``features``: one array per frame, rows ``[id, x, y, orientation]``,
positions in centimetres; ``timestamp``: one per frame) and ``groundtruth.mat`` (``GTgroups``: per annotated
frame a cell of groups, each an array of member ids; ``GTtimestamp``: the annotated frames' time stamps). Only
annotated frames are read. Positions come out in metres.

Bad input raises ``CalibrationError`` naming the file and the field: a missing file or variable, an annotated
frame with no features frame or no people, a feature row that is not ``[id, x, y, orientation]``, a member id
that never has a position in the file. A member missing from one frame only (a tracker drop-out: 9 groups of
Cocktail Party) makes that group incomplete: it is skipped and counted in ``Dataset.skipped``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ..params import CalibrationError

CM = 0.01  # the files' unit (centimetres) in metres
FEATURES, GROUNDTRUTH = "features.mat", "groundtruth.mat"


@dataclasses.dataclass(frozen=True)
class RealGroup:
    """One annotated group in one frame: members' ground positions (n, 2) in metres and orientations (n,) rad."""

    dataset: str
    frame: int  # index among the annotated frames
    ids: tuple[int, ...]
    xy: np.ndarray
    yaw: np.ndarray

    @property
    def n(self) -> int:
        return len(self.ids)


@dataclasses.dataclass(frozen=True)
class Dataset:
    """The groups of one dataset folder; ``skipped`` lists (frame, ids) of groups with a member not located."""

    name: str
    groups: list[RealGroup]
    skipped: list[tuple[int, tuple[int, ...]]]
    quantised: bool  # orientations only take multiples of 90 deg (Coffee Break): unusable as orientations


def _load(path: Path, keys: tuple[str, ...]) -> dict[str, Any]:
    from scipy.io import loadmat

    if not path.is_file():
        raise CalibrationError(f"{path}: file not found (a dataset folder holds {FEATURES} and {GROUNDTRUTH})")
    try:
        data = loadmat(str(path))
    except Exception as exc:  # scipy's parser fails on foreign bytes in many ways (IndexError, zlib.error, ...)
        raise CalibrationError(f"{path}: not a readable .mat file ({type(exc).__name__}: {exc})") from exc
    found = sorted(k for k in data if not k.startswith("__"))
    for key in keys:
        if key not in data:
            raise CalibrationError(f"{path}: no variable '{key}' (found {found}; expected {list(keys)}, "
                                   f"see shared/data/fformations/SOURCES.md)")
    return data


def _cells(path: Path, key: str, value: Any) -> list[Any]:
    arr = np.asarray(value)
    if arr.dtype != object:
        raise CalibrationError(f"{path}: '{key}' is a {arr.dtype} array; expected a cell array (one per frame)")
    return list(arr.ravel())


def _stamps(path: Path, key: str, value: Any, count: int) -> list[int]:
    arr = np.asarray(value).ravel()
    if arr.size != count or not np.issubdtype(arr.dtype, np.number):
        raise CalibrationError(f"{path}: '{key}' holds {arr.size} values ({arr.dtype}); expected {count} numbers, "
                               f"one per frame")
    return [int(t) for t in arr]


def _member_ids(path: Path, frame: int, group: Any) -> tuple[int, ...]:
    ids = np.asarray(group).ravel()
    if ids.size == 0 or not np.issubdtype(ids.dtype, np.number):
        raise CalibrationError(f"{path}: 'GTgroups' frame {frame}: a group with no member ids ({ids.dtype})")
    return tuple(int(i) for i in ids)


def load_dataset(folder: str | Path, name: str | None = None) -> Dataset:
    """Read one dataset folder (``features.mat`` + ``groundtruth.mat``); errors name the file and field."""
    folder = Path(folder)
    fpath, gpath = folder / FEATURES, folder / GROUNDTRUTH
    feat = _load(fpath, ("features", "timestamp"))
    truth = _load(gpath, ("GTgroups", "GTtimestamp"))
    frames = _cells(fpath, "features", feat["features"])
    stamps = _stamps(fpath, "timestamp", feat["timestamp"], len(frames))
    annotated = _cells(gpath, "GTgroups", truth["GTgroups"])
    gt_stamps = _stamps(gpath, "GTtimestamp", truth["GTtimestamp"], len(annotated))
    if not annotated:
        raise CalibrationError(f"{gpath}: 'GTgroups' is empty (no annotated frames)")
    index = {t: i for i, t in enumerate(stamps)}
    rows: list[np.ndarray] = []
    for k, t in enumerate(gt_stamps):
        if t not in index:
            raise CalibrationError(f"{gpath}: 'GTtimestamp' frame {k} ({t}) has no frame in {fpath.name} "
                                   f"'timestamp'")
        try:
            r = np.asarray(frames[index[t]], dtype=float)
        except (TypeError, ValueError):  # text, or ragged rows
            raise CalibrationError(f"{fpath}: 'features' frame {index[t]} is not numeric; expected finite rows "
                                   f"[id, x, y, orientation]") from None
        if r.size == 0:
            raise CalibrationError(f"{fpath}: 'features' frame {index[t]} (annotated frame {k}, time stamp {t}) "
                                   f"is empty; an annotated frame needs its people's positions")
        if r.ndim != 2 or r.shape[1] != 4 or not np.isfinite(r).all():
            raise CalibrationError(f"{fpath}: 'features' frame {index[t]} has shape {r.shape}; expected finite "
                                   f"rows [id, x, y, orientation]")
        rows.append(r)
    seen = {int(i) for r in rows for i in r[:, 0]}
    groups: list[RealGroup] = []
    skipped: list[tuple[int, tuple[int, ...]]] = []
    label = name or folder.name
    for k, (cell, r) in enumerate(zip(annotated, rows, strict=True)):
        where = {int(i): j for j, i in enumerate(r[:, 0])}
        for group in np.asarray(cell, dtype=object).ravel():
            ids = _member_ids(gpath, k, group)
            never = [i for i in ids if i not in seen]
            if never:
                raise CalibrationError(f"{gpath}: 'GTgroups' frame {k}: member id(s) {never} have no position in "
                                       f"any frame of {fpath.name} 'features'")
            if any(i not in where for i in ids):
                skipped.append((k, ids))
                continue
            sel = r[[where[i] for i in ids]]
            groups.append(RealGroup(label, k, ids, sel[:, 1:3] * CM, sel[:, 3].copy()))
    yaw = np.concatenate([r[:, 3] for r in rows])
    quantised = bool(np.allclose(np.remainder(yaw + 1e-9, math.pi / 2), 0.0, atol=1e-6))
    return Dataset(label, groups, skipped, quantised)


def find_datasets(paths: Iterable[str | Path]) -> list[Path]:
    """Dataset folders (holding ``features.mat``) at or below each path, sorted; a path with none raises."""
    out: list[Path] = []
    for p in map(Path, paths):
        if not p.exists():
            raise CalibrationError(f"{p}: not found (give F-formation dataset folders or a folder above them)")
        if not p.is_dir():
            raise CalibrationError(f"{p}: a file; expected a dataset folder holding {FEATURES} and {GROUNDTRUTH}, or "
                                   "a folder above such folders (layout in shared/data/fformations/SOURCES.md)"
                                   + (f": give its folder, {p.parent}" if p.name in (FEATURES, GROUNDTRUTH) else ""))
        found = sorted({f.parent for f in ([p / FEATURES] if (p / FEATURES).is_file() else p.rglob(FEATURES))})
        if not found:
            raise CalibrationError(f"{p}: no {FEATURES} at or below it (expected the layout in "
                                   f"shared/data/fformations/SOURCES.md)")
        out += found
    return out


def load_datasets(paths: Iterable[str | Path]) -> list[Dataset]:
    """Every dataset below ``paths``, named by its folder relative to the path given (e.g. ``CoffeeBreak/Seq1``)."""
    out = []
    for p in map(Path, paths):
        for folder in find_datasets([p]):
            rel = folder.relative_to(p).as_posix() if folder != p else folder.name
            out.append(load_dataset(folder, rel))
    return out
