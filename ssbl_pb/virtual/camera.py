"""The virtual Pepper's CameraTop, rendered in its own process (``Camera``): PyBullet holds the interpreter lock
while it renders, which would stall the qi services that answer deploy's calls."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from ..deploy.robot import Frame
from ..env.view.world import World
from .robot import SimRobot
from .walkers import StrangerBodies


def _render_worker(conn: Any, world: Any, robot: Any, social: Any, body_seed: int = 0) -> None:
    """The camera process: renders scenes sent over ``conn`` until it receives None."""
    w = World(world, robot, social)
    w.set_body_seed(body_seed)  # the members wear the bodies they wear in the robot's world
    w.reset(np.random.default_rng(0), n_humans=2)  # warm up (group data, compiled code, the renderer) before
    w.render_first_person(64, 48)  # the first request: a subscriber's first frame must not come late
    strangers = StrangerBodies()
    try:
        while (msg := conn.recv()) is not None:  # EOFError: the virtual Pepper died
            t, pose, pos, yaw, extra, size = msg
            if w.group is None or w.group.n != len(pos):
                w.reset(np.random.default_rng(0), n_humans=len(pos))
            w.base.pose = pose
            w.group.pos[:], w.group.yaw[:] = pos, yaw
            w.invalidate()
            strangers.show(w.client, extra)
            conn.send((t, w.render_first_person(*size)[0]))
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass
    finally:
        w.close()


class Camera:
    """CameraTop rendered in its own process: PyBullet holds the interpreter lock while it renders (25-40 ms a
    QVGA frame on a loaded machine, measured), which would stall the qi services that answer deploy's calls."""

    def __init__(self, robot: SimRobot) -> None:
        import multiprocessing as mp

        self.robot = robot
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        w = robot.world
        self.proc = ctx.Process(target=_render_worker, args=(child, w.params, w.robot_params, w.social, w.body_seed),
                                daemon=True)
        self.proc.start()
        self.busy = threading.Event()
        self._rx = threading.Thread(target=self._receive, name="camera", daemon=True)
        self._rx.start()

    def request(self) -> None:
        """Render the scene as it is now (skipped while the previous frame is still being rendered)."""
        if self.busy.is_set():
            return
        self.busy.set()
        t, pose, pos, yaw, extra = self.robot.scene()
        self.conn.send((t, pose, pos, yaw, extra, self.robot.image_size))

    def _receive(self) -> None:
        try:
            while True:
                t, img = self.conn.recv()
                self.robot.set_frame(Frame(img, t))
                self.busy.clear()
        except (EOFError, OSError):
            pass

    def close(self) -> None:
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(2.0)
        if self.proc.is_alive():
            self.proc.kill()
