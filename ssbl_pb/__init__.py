"""ssbl-pb: Staged Social Behavior Learning (Gao et al., RO-MAN 2019) for Pepper in PyBullet."""

import gymnasium as _gym

__version__ = "0.1.0"

ENV_ID = "ssbl_pb/ApproachGroup-v0"
if ENV_ID not in _gym.registry:
    _gym.register(id=ENV_ID, entry_point="ssbl_pb.env.gymenv.approach:make_env")
