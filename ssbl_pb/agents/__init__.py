"""On top of the env: the baselines and trained policies, seeded rollouts and per-episode metrics."""
