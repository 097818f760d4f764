"""Actor-critic policies whose Gaussian mean is bounded to the action box by a tanh.

SB3's default Gaussian policy clips *samples* to the action box, so nothing stops the mean from drifting beyond
it: once the mean of a dimension sits several standard deviations past the bound, every sample is clipped to the
same value, that dimension stops exploring and the policy cannot learn out of it. Our Vector policies did exactly
that: means of 2.5-3.7 on both axes pinned the command at (1, 1), a 45-degree inward spiral at full speed, and
the robot drove into members it had to pass on the way round a group (docs/benchmarks.md). A tanh on the mean
keeps it inside [-1, 1], so half the samples at a saturated mean still fall inside the box and PPO keeps a
gradient. Only the mean is squashed, not the samples, so log-probabilities stay those of a plain Gaussian.
"""

from __future__ import annotations

from typing import Any

from sb3_contrib.common.recurrent.policies import (
    RecurrentActorCriticCnnPolicy,
    RecurrentActorCriticPolicy,
    RecurrentMultiInputActorCriticPolicy,
)
from stable_baselines3.common.policies import ActorCriticCnnPolicy, ActorCriticPolicy, MultiInputActorCriticPolicy
from torch import nn


class _BoundedMean:
    """Mixin: after the usual build, the action head ends in a tanh (its weights are the same objects, so the
    optimizer built by ``_build`` still holds them)."""

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)  # type: ignore[misc]
        self.action_net = nn.Sequential(self.action_net, nn.Tanh())


class BoundedMlpPolicy(_BoundedMean, ActorCriticPolicy):
    """``MlpPolicy`` with a tanh-bounded mean."""


class BoundedCnnPolicy(_BoundedMean, ActorCriticCnnPolicy):
    """``CnnPolicy`` with a tanh-bounded mean."""


class BoundedMultiInputPolicy(_BoundedMean, MultiInputActorCriticPolicy):
    """``MultiInputPolicy`` with a tanh-bounded mean."""


class BoundedMlpLstmPolicy(_BoundedMean, RecurrentActorCriticPolicy):
    """sb3-contrib's ``MlpLstmPolicy`` with a tanh-bounded mean."""


class BoundedCnnLstmPolicy(_BoundedMean, RecurrentActorCriticCnnPolicy):
    """sb3-contrib's ``CnnLstmPolicy`` with a tanh-bounded mean."""


class BoundedMultiInputLstmPolicy(_BoundedMean, RecurrentMultiInputActorCriticPolicy):
    """sb3-contrib's ``MultiInputLstmPolicy`` with a tanh-bounded mean."""


def bounded_policy(obs_mode: str, recurrent: bool) -> type:
    """The bounded-mean policy class for an observation mode (feed-forward or LSTM)."""
    if recurrent:
        return {"vector": BoundedMlpLstmPolicy, "camera": BoundedCnnLstmPolicy,
                "camera_speed": BoundedMultiInputLstmPolicy}[obs_mode]
    return {"vector": BoundedMlpPolicy, "camera": BoundedCnnPolicy, "camera_speed": BoundedMultiInputPolicy}[obs_mode]
