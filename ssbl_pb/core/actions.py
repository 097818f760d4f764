"""The agent's action pipeline, in its one order: (1) smoothing (``ActionFilter``), (2) the safety shield
(``core.shield``), both in ``ActionStages``; (3) ``take_over``: where the robot's own perception drives it (a search
while it knows too few people, a look at a member before a claim), its command replaces the policy's. Stages 1-2
belong to the learned agent and run wherever it runs; stage 3 runs where perception runs: the engine with the
observation model (``BatchedApproach.step``) and deploy's loop on the robot (its search, look, hold and dock
states, ``deploy.loop``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import UserError
from .shield import SafetyShield, ShieldParams


class ExponentialFilter:
    """``y_t = y_{t-1} + alpha (x_t - y_{t-1})`` per row of a batch (or of one vector), started at the first
    input; ``alpha = 1`` passes the input through. The stateful filter behind the action smoothing and the
    encoded features' low-pass (``env.gymenv.encoded``)."""

    def __init__(self, alpha: float) -> None:
        self.alpha = float(alpha)
        self.state: np.ndarray | None = None
        self._fresh: np.ndarray | None = None  # rows (of a batch) whose episode has just begun

    def reset(self, rows: list[int] | None = None) -> None:
        """Forget the past inputs (of the given rows of a batch only, when ``rows`` is given)."""
        if rows is None or self.state is None:
            self.state, self._fresh = None, None
            return
        if self._fresh is None:
            self._fresh = np.zeros(len(self.state), dtype=bool)
        self._fresh[rows] = True

    def peek(self, x: np.ndarray) -> np.ndarray:
        """The output for input ``x`` without advancing the state (rows flagged fresh pass ``x`` through)."""
        x = np.asarray(x, dtype=np.float32)
        if self.state is None:
            return x
        new = (self.state + self.alpha * (x - self.state)).astype(np.float32)
        return new if self._fresh is None else np.where(self._fresh[:, None], x, new)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.state = self.peek(x)
        self._fresh = None
        return self.state


class ActionFilter(ExponentialFilter):
    """The action smoothing's filter (``ActionStages``; one row per copy in the batched training env): actions
    clipped to [-1, 1], then filtered."""

    def __call__(self, action: np.ndarray) -> np.ndarray:
        return super().__call__(np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0))


class ActionStages:
    """The agent's first two action stages in their one order, for training (``training.vec_env``,
    ``training.run.EnvFactory``), evaluation and deploy (``trained.TrainedPolicy``): the action clipped and smoothed
    (``ActionFilter`` with ``smoothing``, ``u_t = u_{t-1} + alpha (a_t - u_{t-1})``; 1: off), then the safety shield
    (``shield``: its ``ShieldParams``, None: off) on the Vector observation the action answers, so the shield acts
    last. One action or a batch of rows (one per copy). Part of the learned agent, not of the robot (the paper: "a
    smoothing algorithm can also be applied to the learned policy"): the closed loop is the same in training,
    evaluation and deploy."""

    def __init__(self, smoothing: float = 1.0, shield: ShieldParams | None = None) -> None:
        if not 0.0 < smoothing <= 1.0:
            raise UserError(f"action smoothing alpha {smoothing!r}: expected a number in (0, 1]")
        self.filter = ActionFilter(smoothing) if smoothing < 1.0 else None
        self.shield = SafetyShield(shield) if shield is not None else None

    @classmethod
    def of(cls, env: Any, smoothing: float = 1.0, shield: bool = True, at_place: bool = False) -> ActionStages:
        """The stages for an env's robot (anything holding ``robot_params``, ``social`` and ``task``: an env's
        core, deploy's ``Setup``): the shield ``ShieldParams.of(env, at_place)`` when ``shield``."""
        return cls(smoothing, ShieldParams.of(env, at_place) if shield else None)

    def reset(self, rows: list[int] | None = None) -> None:
        """A new episode (of the given rows of a batch only): the filter forgets the past actions."""
        if self.filter is not None:
            self.filter.reset(rows)

    def __call__(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        a = action if self.filter is None else self.filter(action)
        return a if self.shield is None else self.shield(obs, a)


def take_over(actions: np.ndarray, driven: np.ndarray, body: np.ndarray, max_speed: float) -> np.ndarray:
    """Stage 3: rows ``driven`` (N,) bool get perception's body command ``body`` (N, 2; forward, left in m/s) as
    their action, scaled to the action's [-1, 1] by ``max_speed``, their other entries (turn) zero; the others
    pass unchanged. ``actions`` (N, A) is not modified."""
    if not driven.any():
        return actions
    out = np.array(actions, copy=True)
    out[driven] = 0.0
    out[driven, :2] = body[driven] / max_speed
    return out
