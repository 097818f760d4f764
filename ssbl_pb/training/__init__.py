"""Training with SB3 PPO / sb3-contrib RecurrentPPO: config, callbacks, run directories, learning curves."""
