"""Deploy's looks at the members it has not seen lately: before it claims success, and when it stands away from its
place. One implementation for ``deploy.loop.DeployLoop`` and the observation model (``simulated.PerceivedGroups``),
which turn the robot in place toward the member a look picks (ours: the paper's robot saw the true state)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

ARRIVAL_MARGIN = 0.1  # m inside the success rule's slot tolerance asked of the estimate: the shield's speed cap
#   brings the robot in slowly right where the tolerance begins, and the slot estimated from tracked people errs by
#   a few centimetres (virtual Pepper: 6 of 20 arrivals judged on the estimate were 0.31-0.33 m out)
HEADING_MARGIN = 10.0  # deg inside the success rule's heading tolerance (at most half of it) likewise: turning
#   back to the group after a look it claimed at 19 deg from its estimated centre, 23 deg from the true one
CLAIM_HOLD_S = 1.0  # s the success rule must hold on the estimate, tick after tick, before a claim: the slot
#   estimated from tracked people jitters by +-0.05 m between ticks, and a person's position corrected by 0.27 m
#   when seen again moved it by 0.18 m in one tick; claimed on the first tick under the margin, 3 of 20 `mixed`
#   lockstep claims were 0.29-0.31 m from the true place or 24 deg off the true centre
LOOK_S = 8.0  # s a look at a member not seen lately may take: a half turn at the search's 0.5 rad/s and 1.7 s to
#   detect them; one not seen by then (gone, or a track of nobody) is looked for again later
CONFIRM_S = 4.0  # s: the default of ``Looks.confirm_s`` (``DeployParams.confirm_s``, ``PerceptionParams.confirm_s``)
STALL_S = 5.0  # s the robot may stand (slower than the stop speed) away from its estimated place before it looks
#   at the member seen longest ago (``Looks.unstick``): over qi, a run stood 60 s at the true place while two
#   remembered members, never looked at again, put its estimated place 1.96 m away


def claim_rule(slot_distance: float, speed: float, heading: float, task: Any) -> bool:
    """The simulator's success rule (``TaskParams``: slot tolerance, stop speed, heading tolerance) on the estimate,
    with ``ARRIVAL_MARGIN`` and ``HEADING_MARGIN`` to spare; ``heading`` (rad) from the robot's heading to the
    estimated centre."""
    tol_deg = task.heading_tolerance_deg
    return (slot_distance < task.slot_tolerance - ARRIVAL_MARGIN and speed < task.stop_speed
            and abs(heading) < math.radians(tol_deg - min(HEADING_MARGIN, tol_deg / 2)))


@dataclasses.dataclass
class Looks:
    """Which member to look at, by time (s) and the members' ids and ``seen`` flags (``group.Member``).

    ``confirm_s``: a claim is backed by members detected at or after ``confirm_s`` before it was first tried at
    this place (``DeployParams.confirm_s``). Ours: at its place the neighbours stand outside the 56 deg camera,
    remembered, and the place computed from them; against the virtual Pepper 4 of 19 claims on `mixed` were
    0.28-0.44 m from the true place (tools/bench_deploy.py --lockstep). Asking instead for every member within 4 s
    of now, a look at one neighbour outlasted the other's 4 s, and 3 of 20 runs that had joined never claimed it."""

    confirm_s: float = CONFIRM_S
    seen_at: dict[int, float] = dataclasses.field(default_factory=dict)  # member id -> when last detected
    success_since: float | None = None  # since when the success rule has held on the estimate
    claim_from: float | None = None  # when the claim was first tried at this place
    look: tuple[int, float] | None = None  # the member looked at before a claim, and since when
    looked: set[int] = dataclasses.field(default_factory=set)  # looked at in vain since the claim was first tried
    still_since: float | None = None  # since when the robot stands away from its place
    stall_look: tuple[int, float] | None = None  # the member ``unstick`` looks at, and since when

    def saw(self, members: list[Any], now: float) -> None:
        """The members detected in this frame (``seen``) were seen ``now``."""
        self.seen_at.update({m.id: now for m in members if m.seen})

    def new_approach(self) -> None:
        """A new approach: no claim, look or stall under way."""
        self.claim_from, self.look, self.still_since, self.stall_look = None, None, None, None

    def left_place(self) -> None:
        """The robot is away from its place: a claim starts afresh."""
        self.claim_from, self.look = None, None

    def held(self, success: bool, now: float) -> bool:
        """Whether the success rule has held on the estimate for ``CLAIM_HOLD_S``, tick after tick, by ``now``."""
        if not success:
            self.success_since = None
            return False
        if self.success_since is None:
            self.success_since = now
        return now - self.success_since >= CLAIM_HOLD_S - 1e-9

    def decide(self, members: list[Any], now: float, success: bool, slot_distance: float, speed: float, task: Any
               ) -> tuple[bool, str | None, int | None]:
        """One control period as deploy's loop takes it: whether the claim's rule (``success``, on the estimate)
        has held for ``CLAIM_HOLD_S`` (``held``), and the look due now, ``"confirm"`` (before a claim) or ``"look"``
        (stalled short of the claim's margin, slower than the task's stop speed), with the index of the
        member to turn toward; (held, None, None) when the policy drives or the claim stands."""
        held = self.held(success, now)
        away = slot_distance >= task.slot_tolerance
        if away:  # away from the place: a claim starts afresh
            self.left_place()
        k = self.confirm(members, now, held)
        if k is not None:
            return held, "confirm", k
        # short of where a claim may hold, standing (or docking slowly) there: between the claim's margin and the
        # tolerance too, where over qi a dock braked by the members' clearance stood 65 s 0.25 m from an estimated
        # place that two members remembered out of view put 0.22 m from the true one (the robot stood 0.03 m from it)
        short = slot_distance >= task.slot_tolerance - ARRIVAL_MARGIN
        k = self.unstick(members, now, short and speed < task.stop_speed)
        return held, None if k is None else "look", k

    def confirm(self, members: list[Any], now: float, claim: bool) -> int | None:
        """None when the claim (``claim``: the success rule has held for ``CLAIM_HOLD_S``) can be backed, or when no
        claim is tried and no look is under way; else the index of the member to look at.

        A look at the one detected longest ago goes on until they are detected or for ``LOOK_S``, whether or not
        the rule still holds as the robot turns; the policy then turns it back to the group. A member looked at for
        ``LOOK_S`` in vain holds the claim back no more at this place: the tracker forgets one whose place is in
        clear view, so they stand hidden behind someone nearer. Over qi a look at such a member, straight ahead,
        began again every ``LOOK_S`` for 60 s, and a run that had joined never claimed it."""
        if self.look is None and not claim:
            return None
        if self.claim_from is None:
            self.claim_from, self.looked = now, set()
        since = self.claim_from - self.confirm_s
        seen = [self.seen_at.get(m.id, -math.inf) for m in members]
        stale = [k for k, t in enumerate(seen) if t < since and members[k].id not in self.looked]
        if self.look is not None and (now - self.look[1] > LOOK_S
                                      or all(members[k].id != self.look[0] for k in stale)):
            if now - self.look[1] > LOOK_S:
                self.looked.add(self.look[0])
                stale = [k for k in stale if members[k].id != self.look[0]]
            self.look = None  # seen (or given up on): the policy turns back; the next try looks at the next one
            if not claim:
                return None
        if not stale:
            return None
        if self.look is None:
            self.look = (members[min(stale, key=lambda k: seen[k])].id, now)
        return next(k for k in stale if members[k].id == self.look[0])

    def unstick(self, members: list[Any], now: float, stalled: bool) -> int | None:
        """The index of the member seen longest ago (not within ``confirm_s``) to look at once the robot has stood
        away from its estimated place (``stalled``) for ``STALL_S``; the look goes on until they are detected (or
        forgotten) or for ``LOOK_S``, then the policy has ``STALL_S`` again. None otherwise."""
        if self.stall_look is not None:
            k = next((k for k, m in enumerate(members) if m.id == self.stall_look[0]), None)
            if k is not None and not members[k].seen and now - self.stall_look[1] <= LOOK_S:
                return k
            self.stall_look, self.still_since = None, now
            return None
        if not stalled:
            self.still_since = None
            return None
        if self.still_since is None:
            self.still_since = now
        seen = [self.seen_at.get(m.id, -math.inf) for m in members]
        stale = [k for k, t in enumerate(seen) if t < now - self.confirm_s]
        if now - self.still_since < STALL_S or not stale:
            return None
        k = min(stale, key=lambda k: seen[k])
        self.stall_look = (members[k].id, now)
        return k
