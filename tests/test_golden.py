"""A golden seeded rollout of the engine: its trajectory for fixed seeds and a fixed action sequence, stored, and
compared to 1e-9, so a change that moves the simulation by any amount fails here first (and says where).

After an intended change of the dynamics, regenerate it and say why in the commit:
    .venv/bin/python tests/test_golden.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

GOLDEN = Path(__file__).resolve().parent / "golden" / "engine.npz"
SCENARIOS = ("mixed", "mixed@furnished")


def rollout() -> dict[str, np.ndarray]:
    """4 copies per scenario, seeds 100-103, 120 steps of actions from a seeded generator, resets as they end."""
    from ssbl_pb.env.engine.batched import BatchedApproach

    out: dict[str, list[np.ndarray]] = {"obs": [], "reward": [], "pose": [], "members": []}
    rng = np.random.default_rng(5)
    for scenario in SCENARIOS:
        b = BatchedApproach(4, scenario)
        for i in range(4):
            b.seed(i, 100 + i)
            b.reset(i)
        for _ in range(120):
            out["obs"].append(b.observations())
            reward, terminated, truncated = b.step(rng.uniform(-1.0, 1.0, (4, b.n_act)))
            out["reward"].append(reward)
            out["pose"].append(b.pose.copy())
            out["members"].append(b.pos.copy())
            for i in np.flatnonzero(terminated | truncated).tolist():
                b.reset(i)
    return {k: np.asarray(v) for k, v in out.items()}


def test_the_engine_plays_its_golden_rollout():
    want = np.load(GOLDEN)
    got = rollout()
    for key in want.files:
        diff = np.abs(got[key].astype(float) - want[key].astype(float))
        step = int(np.unravel_index(diff.argmax(), diff.shape)[0]) if diff.size else 0
        assert diff.max() <= 1e-9, f"{key} moved by {diff.max():.3g} (first at step {step} of the rollout)"


if __name__ == "__main__":
    GOLDEN.parent.mkdir(exist_ok=True)
    np.savez_compressed(GOLDEN, **rollout())
    print(f"wrote {GOLDEN}", file=sys.stderr)
