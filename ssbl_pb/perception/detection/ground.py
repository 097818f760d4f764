"""A person's ground position from a box in a robot camera's image: the feet on the floor (pushed back by the
legs' radius), else the head top at its known height; torso boxes (the colour detector) from the torso's two
planes. Heights are the simulated proxy's (``ProxyGeometry``, ``urdf/human.urdf``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..camera import PinholeCamera, pixel_to_plane

LEG_RADIUS = 0.16  # m, the proxy's leg cylinder (urdf/human.urdf)


@dataclasses.dataclass(frozen=True)
class ProxyGeometry:
    """Heights (m above the floor) of the rendered proxy's head top and torso box."""

    head_top: float = 1.70  # urdf/human.urdf
    torso: tuple[float, float] = (0.84, 1.44)


def boxes_to_ground(cam: PinholeCamera, boxes: np.ndarray, geom: ProxyGeometry | None = None,
                    margin: float = 1.0, torso: bool = False) -> np.ndarray:
    """Person boxes ``x, y, w, h`` (n, >=4) -> robot-frame centres (n, 2); NaN when neither end is visible.

    ``torso=True`` treats boxes as torso boxes (``ColourDetector``): the mean of the top and bottom edges'
    intersections with the torso's top and bottom planes."""
    boxes = np.asarray(boxes, dtype=float)
    boxes = boxes.reshape(-1, boxes.shape[-1] if boxes.ndim == 2 else 5)
    out = np.full((len(boxes), 2), np.nan)
    if not len(boxes):
        return out
    g = geom or ProxyGeometry()
    u = boxes[:, 0] + (boxes[:, 2] - 1) / 2.0
    top, bottom = boxes[:, 1], boxes[:, 1] + boxes[:, 3] - 1
    if torso:
        a = pixel_to_plane(cam, np.column_stack([u, top]), g.torso[1])
        b = pixel_to_plane(cam, np.column_stack([u, bottom]), g.torso[0])
        ok_t = top > margin
        ok_b = bottom < cam.height - 1 - margin
        both = ok_t & ok_b
        out[both] = 0.5 * (a[both] + b[both])
        return out
    feet = pixel_to_plane(cam, np.column_stack([u, bottom + 0.5]), 0.0)
    head = pixel_to_plane(cam, np.column_stack([u, top - 0.5]), g.head_top)
    use_feet = bottom < cam.height - 1 - margin
    use_head = ~use_feet & (top > margin)
    rng = np.linalg.norm(feet - cam.centre()[None, :2], axis=1, keepdims=True)
    pushed = feet + LEG_RADIUS * (feet - cam.centre()[None, :2]) / np.maximum(rng, 1e-9)
    out[use_feet] = pushed[use_feet]
    out[use_head] = head[use_head]
    return out
