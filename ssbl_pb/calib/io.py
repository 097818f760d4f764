"""File helpers of the calibration tools (YAML in the ROS layout, images, figures) and their error type.

Every output is written to a temporary file in the destination folder and renamed over the target, so a crash
or a bad input never leaves a half-written file behind.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from ..files import atomic_write, check_output_path, write_text
from ..params import ConfigError


class CalibrationError(ConfigError):
    """Bad calibration input (a file, a field, too few usable samples); the message names the file."""


def check_outputs(out: Path, beside: Sequence[str] = (), flag: str = "--out") -> None:
    """Check, before any work, that ``out`` and the files written beside it (``out`` with each suffix of
    ``beside``, e.g. ".png", ".md") can be written; ``UserError`` naming ``flag`` otherwise."""
    check_output_path(out, flag, is_dir=False)
    for suffix in beside:
        side = out.with_suffix(suffix)
        if side == out:
            raise CalibrationError(f"{flag} {out}: the {suffix} file goes beside it with the same name; give "
                                   f"another suffix (e.g. .yaml)")
        check_output_path(side, f"{flag} {out}: its {suffix} file", is_dir=False)


class _Dumper(yaml.SafeDumper):
    """Block mappings, flow lists (as ROS camera_info files are written)."""


def _list_flow(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True)


_Dumper.add_representer(list, _list_flow)


def write_yaml(path: str | Path, data: dict[str, Any], header: str = "") -> Path:
    """Write a mapping as block-style YAML (lists inline) atomically, with an optional ``#`` comment header."""
    body = yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False, width=100)
    head = "".join(f"# {line}\n" for line in header.splitlines()) if header else ""
    return write_text(path, head + body)


def write_image(path: str | Path, image: Any) -> Path:
    """Write an image (numpy array, BGR or grey) atomically with OpenCV."""
    import cv2

    def _w(p: Path) -> None:
        if not cv2.imwrite(str(p), image):
            raise CalibrationError(f"{path}: OpenCV could not write the image")

    return atomic_write(path, _w)


def save_figure(path: str | Path, fig: Any, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically and close it."""
    import matplotlib.pyplot as plt

    try:
        return atomic_write(path, lambda p: fig.savefig(p, dpi=dpi, bbox_inches="tight"))
    finally:
        plt.close(fig)
