"""Named scenarios: which groups are spawned and where the robot starts.

``default`` is the paper's 2-member vis-a-vis group with the robot starting anywhere around it. Each other
name fixes a formation (sizes 2-5 where the formation allows), ``real`` places groups of 2-5 exactly as in
annotated real frames (``layouts.real_layout``), ``behind`` starts the robot behind a member, ``FORMATION-N``
fixes both (e.g. ``circular-4``, ``real-3``), a comma-separated list mixes names uniformly, and ``mixed``
samples every formation (``real`` included), size and start.

A name may end in ``@ROOM`` for the room the episodes play in (``rooms``): ``@empty`` (the walls of
``WorldParams.room_size``), ``@furnished`` (a new random furnished room every episode) or ``@map`` (the room YAML's
obstacles, e.g. from ``tools/import_map.py``). Without it the room is the empty one, or the room YAML's when it has
obstacles. ``mixed@furnished,default`` mixes furnished rooms with the paper's empty one.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...core.layouts import LAYOUTS
from ...errors import UserError

STARTS = ("any", "behind")
ROOMS = ("empty", "furnished", "map")


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A family of episodes: group sizes, formations and where the robot starts."""

    name: str
    sizes: tuple[int, ...]
    formations: tuple[str, ...]
    start: str = "any"
    room: str = ""  # "" = the env's default room (``ScenarioMix``), else one of ``ROOMS``

    def sample(self, rng: np.random.Generator) -> tuple[int, str, str]:
        """(group size, formation, start) for one episode."""
        return int(rng.choice(self.sizes)), str(rng.choice(self.formations)), self.start


BASE_SCENARIOS: dict[str, Scenario] = {
    "default": Scenario("default", (2,), ("vis_a_vis",)),
    "vis_a_vis": Scenario("vis_a_vis", (2, 3, 4, 5), ("vis_a_vis",)),
    "l_shape": Scenario("l_shape", (2, 3, 4), ("l_shape",)),
    "side_by_side": Scenario("side_by_side", (2, 3, 4), ("side_by_side",)),
    "circular": Scenario("circular", (3, 4, 5), ("circular",)),
    "behind": Scenario("behind", (2, 3), ("vis_a_vis", "l_shape", "side_by_side"), "behind"),
    "real": Scenario("real", (2, 3, 4, 5), ("real",)),
}
MIXED = ("vis_a_vis", "l_shape", "side_by_side", "circular", "behind", "real")
SCENARIO_NAMES = (*BASE_SCENARIOS, "mixed", "FORMATION-N", "a,b,...")


def _one(name: str, default_room: str) -> list[Scenario]:
    name, at, room = name.partition("@")
    if at and room not in ROOMS:
        raise UserError(f"scenario '{name}@{room}': room {room!r}, expected one of {list(ROOMS)}")
    return [dataclasses.replace(sc, name=f"{sc.name}@{room or default_room}", room=room or default_room)
            for sc in _groups(name.strip())]


def _groups(name: str) -> list[Scenario]:
    if name in BASE_SCENARIOS:
        return [BASE_SCENARIOS[name]]
    if name == "mixed":
        return [BASE_SCENARIOS[m] for m in MIXED]
    form, _, size = name.rpartition("-")
    if form in LAYOUTS and size.isdigit() and 2 <= int(size) <= 5:
        return [Scenario(name, (int(size),), (form,))]
    raise UserError(f"scenario {name!r}: expected one of {list(BASE_SCENARIOS)}, 'mixed', FORMATION-N with "
                     f"FORMATION in {list(LAYOUTS)} and N in 2..5, each optionally @ROOM with ROOM in {list(ROOMS)}, "
                     f"or a comma-separated list of these")


class ScenarioMix:
    """Samples uniformly among the scenarios named in ``spec`` (rooms without ``@ROOM``: ``default_room``)."""

    def __init__(self, spec: str, default_room: str = "empty") -> None:
        if not isinstance(spec, str) or not spec.strip():
            raise UserError(f"scenario {spec!r}: expected a non-empty name")
        self.spec = spec
        self.members = [sc for part in spec.split(",") for sc in _one(part.strip(), default_room)]

    @property
    def rooms(self) -> set[str]:
        """The rooms its episodes may play in."""
        return {sc.room for sc in self.members}

    def pick(self, rng: np.random.Generator) -> Scenario:
        """The scenario of one episode (draws from ``rng`` only when there is a choice)."""
        return self.members[int(rng.integers(len(self.members)))] if len(self.members) > 1 else self.members[0]

    def sample(self, rng: np.random.Generator) -> tuple[int, str, str]:
        """(group size, formation, start) for one episode."""
        return self.pick(rng).sample(rng)


RESET_OPTIONS = ("n_humans", "formation", "start")


def apply_reset_options(sample: tuple[int, str, str], options: dict | None) -> tuple[int, str, str]:
    """(size, formation, start) of a scenario's sample with ``reset(options=...)`` overrides: ``n_humans``
    (2-5), ``formation`` and ``start`` ('any' or 'behind'). The sample is drawn first either way, so an episode's
    other random choices do not depend on the options."""
    if not options:
        return sample
    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        raise UserError(f"reset options {unknown}: expected keys among {list(RESET_OPTIONS)}")
    n, formation, start = sample
    n = options.get("n_humans", n)
    formation = options.get("formation", formation)
    start = options.get("start", start)
    if not isinstance(n, int) or not 2 <= n <= 5:
        raise UserError(f"reset option n_humans = {n!r}: expected an integer in 2..5")
    if formation not in LAYOUTS:
        raise UserError(f"reset option formation = {formation!r}: expected one of {list(LAYOUTS)}")
    if start not in ("any", "behind"):
        raise UserError(f"reset option start = {start!r}: expected 'any' or 'behind'")
    return n, formation, start
