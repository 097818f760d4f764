"""From tracked people to the group the policy sees: the group estimate with its memory of members out of view
(estimate), deploy's looks (looks), and the same chain run on the simulator's state (observation_model)."""
