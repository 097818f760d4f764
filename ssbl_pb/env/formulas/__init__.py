"""The task's compiled formulas and their parameters: forces, members, layouts, base, reward, observation, shield."""
