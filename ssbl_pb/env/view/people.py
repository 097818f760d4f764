"""People at given poses seen from Pepper's camera: any number of the shipped bodies standing in the room
(``PeopleScene``, ``render_people``), for tests and benchmarks of a person detector on simulated frames."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...params import HumansLook, RobotParams, WorldParams
from .bodies import body_order, load_body, park, place
from .world import World


class PeopleScene:
    """Any number of bodies in the room of ``world`` (its floor and walls) with Pepper, rendered from its
    camera. ``show`` stands people; ``render`` takes Pepper's first-person image."""

    def __init__(self, world: WorldParams | None = None, robot: RobotParams | None = None) -> None:
        params = world or WorldParams()
        # the World's own members stay parked proxies: the people here are this scene's bodies
        self.world = World(WorldParams(**{**params.__dict__, "humans": HumansLook("proxy")}), robot)
        self.client = self.world.client
        self._pool: dict[int, list[int]] = {}  # body index -> loaded ids
        self._shown: list[int] = []

    def show(self, people: np.ndarray | Sequence[Sequence[float]], bodies: Sequence[int] | None = None,
             seed: int = 0) -> list[int]:
        """Stand one body per row of ``people`` (x, y m, yaw rad); ``bodies``: the body index of each (default:
        ``body_order(seed)``, repeated when there are more people than bodies). Bodies of an earlier call that
        are not used go back under the floor. Returns the PyBullet ids in ``people``'s order."""
        rows = np.asarray(people, dtype=float).reshape(-1, 3)
        if bodies is None:
            order = body_order(seed)
            bodies = [order[i % len(order)] for i in range(len(rows))]
        if len(bodies) != len(rows):
            raise ValueError(f"bodies: {len(bodies)} indices for {len(rows)} people")
        for body in self._shown:
            park(self.client, body)
        used: dict[int, int] = {}
        ids = []
        for (x, y, yaw), index in zip(rows.tolist(), bodies, strict=True):
            pool = self._pool.setdefault(int(index), [])
            k = used.get(int(index), 0)
            if k == len(pool):
                pool.append(load_body(self.client, int(index)))
            used[int(index)] = k + 1
            place(self.client, pool[k], x, y, yaw)
            ids.append(pool[k])
        self._shown = ids
        return ids

    def render(self, robot_pose: Sequence[float] = (0.0, 0.0, 0.0), width: int = 320, height: int = 240,
               projection: list[float] | None = None,
               segmentation: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Pepper's CameraTop image (H, W, 3) uint8 from a base at ``robot_pose`` (x, y m, yaw rad), optionally
        with the segmentation mask (body ids)."""
        self.world.base.pose = np.asarray(robot_pose, dtype=float)
        self.world.invalidate()
        return self.world.render_first_person(width, height, projection, segmentation)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> PeopleScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render_people(people: np.ndarray | Sequence[Sequence[float]], robot_pose: Sequence[float] = (0.0, 0.0, 0.0),
                  size: tuple[int, int] = (320, 240), bodies: Sequence[int] | None = None, seed: int = 0,
                  world: WorldParams | None = None, robot: RobotParams | None = None) -> np.ndarray:
    """One RGB image (H, W, 3) uint8 from Pepper's camera at ``robot_pose`` (x, y m, yaw rad) of people standing
    at ``people`` (rows x, y m, yaw rad: yaw pi - (bearing) faces the robot); ``size`` (w, h) pixels; ``bodies``
    as in ``PeopleScene.show``. Builds and closes a scene: use a ``PeopleScene`` for many frames."""
    with PeopleScene(world, robot) as scene:
        scene.show(people, bodies, seed)
        return scene.render(robot_pose, *size)[0]
