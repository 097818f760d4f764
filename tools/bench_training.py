#!/usr/bin/env python
"""Training throughput: PPO on the Vector env vs on a trivial env with the same observation and action sizes,
both measured in one run, in two settings:

* ``sb3``: SB3's own defaults (``PPO("MlpPolicy", env)``: one env, 64x64 net, 2048 steps per update, 10 epochs);
  the trivial env in SB3's ``DummyVecEnv``, the Vector env as training runs it (``BatchedVecEnv`` of one copy)
  and, for reference, as a plain Gymnasium env in ``DummyVecEnv`` (``vector_env_dummy``);
* ``config``: our training config (configs/vector_ff.yaml: 8 envs, 2x128 net, VecNormalize, the agent's action
  smoothing, the safety shield and episode monitoring). The Vector env runs as training runs it, batched
  (``training.vec_env.BatchedVecEnv``: all 8 copies in one compiled step); the trivial env runs in SB3's own
  ``DummyVecEnv`` with ``Monitor`` and the smoothing wrapper (all but the shield, which is part of our agent's
  cost). ``vector_env_dummy`` is our env in ``DummyVecEnv`` too (one env object per copy), for reference.

The trivial env returns a stored observation (no sampling), so its figure is SB3's own cost per step.
Writes results/bench_training.json.
    python tools/bench_training.py
"""

from __future__ import annotations

from pathlib import Path

from ssbl_pb.analysis.report import write_json
from ssbl_pb.cli import ArgumentParser, UserError, int_at_least, run
from ssbl_pb.files import check_output_path
from ssbl_pb.training.config import load_config, parse_overrides

ROOT = Path(__file__).resolve().parents[1]

SETTINGS = ("sb3", "config")


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int_at_least(256), default=20_000,
                    help="learning steps per measurement (default 20000)")
    ap.add_argument("--repeats", type=int_at_least(1), default=3, help="measurements per env, median kept (default 3)")
    ap.add_argument("--settings", default=",".join(SETTINGS), help=f"comma list of {SETTINGS} (default both)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a key of configs/vector_ff.yaml for the config setting, e.g. n_envs=16")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench_training.json")
    args = ap.parse_args(argv)
    settings = [s.strip() for s in args.settings.split(",") if s.strip()]
    bad = [s for s in settings if s not in SETTINGS]
    if bad or not settings:
        raise UserError(f"--settings {args.settings!r}: expected a comma list of {SETTINGS}")

    from ssbl_pb.bench.training import CONFIG, measure  # lazy: torch and SB3 (~3 s), which --help does without

    check_output_path(args.out, is_dir=False)
    overrides = parse_overrides(args.set)
    load_config(CONFIG, overrides)  # unknown keys and bad values fail here

    results = {"steps": args.steps, "repeats": args.repeats, "overrides": overrides}
    for s in settings:
        r = measure(s, args.steps, overrides, args.repeats)
        results[s] = r
        print(f"{s:7s} trivial env {r['trivial_steps_per_s']:6.0f} steps/s, Vector env "
              f"{r['vector_env_steps_per_s']:6.0f} steps/s: {r['ratio']:.0%} "
              f"({'PASS' if r['ratio'] >= 0.8 else 'MISS'} >= 80 %); env adds {r['env_us_per_step']:.0f} us/step; "
              f"as a plain gym env in DummyVecEnv {r['vector_env_dummy_steps_per_s']:6.0f} steps/s")
    write_json(args.out, results)
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    run(main)
