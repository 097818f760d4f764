"""The virtual Pepper's NAOqi services: ALMotion, ALVideoDevice and ALMemory with NAOqi's method names and return
layouts (``make_services``), and the ``SSBLVirtualPepper`` identity (``Identity``)."""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import cv2
import numpy as np

from ..core.range_sensors import RANGES
from ..deploy.naoqi import BGR, RESOLUTIONS, RGB, import_qi
from ..deploy.ranges import SONAR_KEYS

MAX_SUBSCRIPTIONS = 6  # NAOqi's limit per subscriber name
PROTECTION_CHAINS = ("Move", "Arms")  # ALMotion's external collision protection groups (the base, the arms)
HANG_S = 2.0  # s a hung stopMove (``--hang-stops``) takes to return, having done nothing


def _chains(name: str) -> tuple[str, ...]:
    """The protection groups ALMotion's ``name`` stands for ("All": every one)."""
    if name not in (*PROTECTION_CHAINS, "All"):
        raise RuntimeError(f"ALMotion: collision protection {name!r}: expected one of {[*PROTECTION_CHAINS, 'All']}")
    return PROTECTION_CHAINS if name == "All" else (name,)


def make_services(vp: Any) -> tuple[Any, Any, Any, Any]:  # vp: the ``pepper.VirtualPepper``
    """ALMotion, ALVideoDevice, ALMemory (``subscriber``, for ALMotion/MoveFailed; ``getData``/``getListData``
    for the base's range sensors) and ALSonar objects with NAOqi's method names and return layouts. As on a
    Pepper with NAOqi before 2.9, the sonars run only while someone subscribes ALSonar (naoqi_driver's
    ``converters/sonar.cpp`` subscribes before it reads their keys): meanwhile ALMemory holds their last echo
    (before any: ``sonar_reported_max``, nothing)."""
    qi = import_qi()
    robot = vp.robot

    @qi.multiThreaded()
    class ALMotion:
        def move(self, x: float, y: float, theta: float) -> None:
            vp._refused = False
            robot.send(np.array([x, y, theta], dtype=float))

        def stopMove(self) -> Any:
            if vp.hang_stops > 0:  # a lost call: answered late, nothing done (a future: no thread held)
                vp.hang_stops -= 1
                vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "stopMove_hung"})
                late = qi.Promise()
                threading.Timer(HANG_S, late.setValue, (None,)).start()
                return late.future()
            robot.stop()
            vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "stopMove"})

        def getRobotPosition(self, use_sensors: bool) -> list[float]:
            frozen = vp.odometry_frozen
            return list(frozen[0]) if frozen else [float(v) for v in robot.odometry().pose]

        def getRobotVelocity(self) -> list[float]:
            frozen = vp.odometry_frozen
            return list(frozen[1]) if frozen else [float(v) for v in robot.odometry().velocity]

        def robotIsWakeUp(self) -> bool:
            return True

        def getExternalCollisionProtectionEnabled(self, name: str) -> bool:
            return all(vp.protection[c] for c in _chains(name))

        def setExternalCollisionProtectionEnabled(self, name: str, enable: bool) -> None:
            for c in _chains(name):
                vp.protection[c] = bool(enable)
            vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "setExternalCollisionProtection",
                      "name": name, "enable": bool(enable)})

    class ALVideoDevice:
        def subscribeCamera(self, name: str, camera: int, resolution: int, colour: int, fps: int) -> str:
            if resolution not in RESOLUTIONS or colour not in (RGB, BGR) or camera != 0:
                raise RuntimeError(f"virtual Pepper: camera {camera}, resolution {resolution}, colour space {colour}"
                                   f" not served (CameraTop 0; resolutions {sorted(RESOLUTIONS)}; RGB 11 or BGR 13)")
            for k in range(MAX_SUBSCRIPTIONS):
                handle = f"{name}_{k}"
                if handle not in vp.subs:
                    vp.subs[handle] = (resolution, colour)
                    robot.image_size = RESOLUTIONS[resolution]
                    vp.fps = max(1, min(int(fps), vp.fps_max))
                    vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "subscribeCamera",
                              "handle": handle})
                    return handle
            raise RuntimeError(f"ALVideoDevice: {MAX_SUBSCRIPTIONS} subscriptions named {name!r} already exist")

        @qi.bind("(iiiiiiriffff)", ("s",))
        def getImageRemote(self, handle: str) -> list[Any]:
            if handle not in vp.subs:
                raise RuntimeError(f"ALVideoDevice.getImageRemote: unknown handle {handle!r}")
            frame = robot.frame() or robot.render()
            resolution, colour = vp.subs[handle]
            w, h = RESOLUTIONS[resolution]
            img = frame.image if frame.image.shape[1] == w else cv2.resize(frame.image, (w, h))
            img = img[..., ::-1] if colour == BGR else img
            stamp = vp.epoch + frame.stamp
            half_h, half_v = math.radians(robot.world.robot_params.camera_hfov_deg) / 2, math.atan(
                math.tan(math.radians(robot.world.robot_params.camera_hfov_deg) / 2) * h / w)
            return [w, h, 3, colour, int(stamp), int(round((stamp % 1.0) * 1e6)) % 1000000,
                    np.ascontiguousarray(img).tobytes(), 0, -half_h, -half_v, half_h, half_v]

        def unsubscribe(self, handle: str) -> bool:
            vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "unsubscribe", "handle": handle})
            return vp.subs.pop(handle, None) is not None

    class Subscriber:
        def __init__(self) -> None:
            self.signal = qi.Signal("m")

    class ALMemory:
        def __init__(self) -> None:
            self.subscribers: dict[str, Subscriber] = {}

        def subscriber(self, key: str) -> Subscriber:
            return self.subscribers.setdefault(key, Subscriber())

        def getData(self, key: str) -> float:
            return self.getListData([key])[0]

        def getListData(self, keys: list[str]) -> list[float]:
            try:
                values = robot.memory_values([str(k) for k in keys])
            except KeyError as exc:  # NAOqi's ALMemory raises on a key it does not hold
                raise RuntimeError(f"ALMemory::getData: no data for key {exc.args[0]!r}") from None
            for k, (key, v) in enumerate(zip(keys, values, strict=True)):
                if key in SONAR_KEYS:  # the sonars' last echo while they ran
                    if vp.sonar_subscribers:
                        vp.sonar_held[key] = v
                    values[k] = vp.sonar_held.get(key, RANGES.sonar_reported_max)
            return values

        @qi.nobind
        def raise_event(self, key: str, value: Any) -> None:
            if key in self.subscribers:
                self.subscribers[key].signal(value)

    class ALSonar:
        def subscribe(self, name: str) -> None:
            vp.sonar_subscribers.add(str(name))
            vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "ALSonar.subscribe", "name": name})

        def unsubscribe(self, name: str) -> None:
            vp.sonar_subscribers.discard(str(name))
            vp.write({"kind": "call", "wall": time.time(), "t": robot.t, "call": "ALSonar.unsubscribe", "name": name})

        def getSubscribersInfo(self) -> list[list[Any]]:
            return [[name, 0, 0.0] for name in sorted(vp.sonar_subscribers)]

    vp.memory = ALMemory()
    return ALMotion(), ALVideoDevice(), vp.memory, ALSonar()


class Identity:
    """``SSBLVirtualPepper``: what deploy needs to know of this robot (``describe``), and its fault switch for
    harnesses (``hangStops``: ``--hang-stops`` armed at a chosen moment)."""

    def __init__(self, facts: dict[str, str], vp: Any = None) -> None:
        self.facts, self._vp = facts, vp

    def describe(self) -> dict[str, str]:
        return dict(self.facts)

    def hangStops(self, n: int) -> None:  # noqa: N802 - a qi method, NAOqi's style
        """Leave the next ``n`` stopMove calls unanswered for ``HANG_S``, doing nothing."""
        if self._vp is not None:
            self._vp.hang_stops = int(n)
            self._vp.write({"kind": "call", "wall": time.time(), "t": self._vp.robot.t, "call": "hangStops", "n": n})
