"""Task parameters of the approaching task: episode length, the success rule and the zones used by metrics."""

from __future__ import annotations

import dataclasses

from numba import njit

from ..params import _check, _positive


@dataclasses.dataclass(frozen=True)
class TaskParams:
    """Success means joining the group properly, not merely getting near it.

    The robot must stand within ``slot_tolerance`` of the free slot (the middle of the widest gap between the
    members, on the o-space circle, as the members stand now), face the conversation centre within
    ``heading_tolerance_deg``, move slower than ``stop_speed``, and never have collided or entered a member's
    intimate zone (either ends the episode as a failure). Tolerances (ours): 0.3 m is about a step and
    a third of Pepper's footprint; 20 deg keeps the group centre well inside the camera's 56 deg view; 0.1 m/s
    is under a third of the NAOqi default speed. Zone distances are between bodies (Pepper's footprint and the
    member's 0.28 m circle), as Hall's proxemic distances are measured between people.
    """

    max_steps: int = 300  # ref: at most 300 decisions per episode (30 s at 10 Hz)
    slot_tolerance: float = 0.3  # m
    heading_tolerance_deg: float = 20.0
    stop_speed: float = 0.1  # m/s
    intimate_zone: float = 0.45  # m, Hall
    personal_zone: float = 1.2  # m, Hall
    social_zone: float = 3.6  # m, Hall; the field-of-view metric counts time within it
    turn: bool = False  # action includes turning; by default the robot faces the group centre (ref)
    heading_gain: float = 2.0  # 1/s, proportional turn toward the centre when ``turn`` is False
    proximity_band: float = 0.3  # m beyond the intimate zone where closing in costs (reward.proximity_cost):
    #                              Pepper's braking distance from 0.35 m/s at 0.3 m/s^2 (0.2 m) plus 0.1 m
    route_margin: float = 0.15  # extra m kept beyond the intimate zone by the shaping's way around the group:
    #                              about four control steps at full speed (0.035 m each), room to correct
    geodesic_route: bool = False  # in rooms with obstacles the shaping's way also goes round the furniture
    #                               (``kernels.route_to_slot``); off: round the group only, as trained before

    def __post_init__(self) -> None:
        _check(isinstance(self.max_steps, int) and self.max_steps >= 1, "task", "max_steps", self.max_steps,
               "an integer >= 1")
        _positive("task", self, "slot_tolerance", "heading_tolerance_deg", "stop_speed", "intimate_zone",
                  "personal_zone", "social_zone", "heading_gain", "proximity_band")
        _check(isinstance(self.route_margin, int | float) and self.route_margin >= 0, "task", "route_margin",
               self.route_margin, "a number >= 0")
        _check(isinstance(self.turn, bool), "task", "turn", self.turn, "true or false")
        _check(isinstance(self.geodesic_route, bool), "task", "geodesic_route", self.geodesic_route,
               "true or false")


@njit(cache=True)
def joined(violation: bool, slot_distance: float, speed: float, heading_error: float, slot_tolerance: float,
           stop_speed: float, heading_tolerance: float) -> bool:
    """The success rule (``TaskParams``): at the free slot, stopped, facing the centre, no violation ever (an
    episode ends at its first violation). ``heading_tolerance`` in radians."""
    return (not violation and slot_distance < slot_tolerance and speed < stop_speed
            and abs(heading_error) < heading_tolerance)
