"""The policy deploy drives with (``--policy``): a baseline by name or a trained Vector model, its shield set for
the robot it runs on (``loop.deploy_shield``). Used by ``python -m ssbl_pb.deploy`` and the deploy benchmark."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ..agents.policies import make_policy
from ..agents.trained import load_trained, shield_at_place
from ..core import observation as ob
from ..core.task import TaskParams
from ..params import RobotParams, SocialParams
from .loop import deploy_shield

BASELINES = ("sffm", "straight", "random")


def load_policy(spec: str, robot: RobotParams, social: SocialParams, task: TaskParams, stop_distance: float) -> Any:
    """A baseline by name or a trained Vector model, its shield braking within this robot's limits and short of
    the stop distance (``loop.deploy_shield``)."""
    if spec in BASELINES:
        return make_policy(spec, robot, social, seed=0, task=task)
    space = gym.spaces.Box(-ob.OBS_LIMIT, ob.OBS_LIMIT, shape=(ob.OBS_SIZE,), dtype=np.float32)
    return load_trained(spec, space, None, deploy_shield(robot, social, task, stop_distance, shield_at_place(spec)))
