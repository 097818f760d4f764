"""File helpers of the calibration tools (output checks, images, figures); their YAML writer is
``files.write_yaml`` and their error type ``params.CalibrationError``.

Every output is written to a temporary file in the destination folder and renamed over the target, so a crash
or a bad input never leaves a half-written file behind.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..files import atomic_write, check_output_path
from ..params import CalibrationError


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
