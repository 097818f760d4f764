"""Person bodies in the PyBullet scene: the shipped bodies (``urdf/bodies``, made by ``tools/make_bodies.py``)
loaded into a client and one chosen per member from a seed (``World`` with ``humans.appearance: body``;
``people.PeopleScene`` stands any number of them).

A body is visual only: its collision shapes are the proxy's (the engine's formulas decide contacts). It stands
with its feet on the floor at its link origin, facing +x (the member's heading).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ...urdf import body_manifest, body_path
from .bullet import pybullet as p

PARKED = (0.0, 0.0, -10.0)  # where unused bodies wait, under the floor


def body_count() -> int:
    """How many bodies are shipped."""
    return len(body_manifest())


def body_order(seed: int) -> list[int]:
    """Body indices in the order members take them for ``seed`` (member i gets entry i; a seeded permutation, so
    a group's members differ)."""
    return [int(k) for k in np.random.default_rng(seed).permutation(body_count())]


def load_body(client: int, index: int, pos: Sequence[float] = PARKED) -> int:
    """Load body ``index`` into ``client`` (parked by default); returns its PyBullet id."""
    return p.loadURDF(str(body_path(index)), list(pos), useFixedBase=True, physicsClientId=client)


def place(client: int, body: int, x: float, y: float, yaw: float) -> None:
    """Stand ``body`` at (x, y) m, facing ``yaw`` rad."""
    p.resetBasePositionAndOrientation(body, [x, y, 0.0], [0, 0, math.sin(yaw / 2), math.cos(yaw / 2)],
                                      physicsClientId=client)


def park(client: int, body: int) -> None:
    p.resetBasePositionAndOrientation(body, PARKED, [0, 0, 0, 1], physicsClientId=client)
