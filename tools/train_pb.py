#!/usr/bin/env python
"""Train an approaching policy with PPO (feed-forward) or RecurrentPPO (LSTM).

Examples:
    python tools/train_pb.py                                   # configs/vector_ff.yaml defaults
    python tools/train_pb.py --config configs/vector_lstm.yaml --total-steps 200000
    python tools/train_pb.py --scenario mixed --out runs/mixed --set reward.w_smooth=0.1
    python tools/train_pb.py --resume runs/ppo_vector          # continue a killed run
    tensorboard --logdir runs/                                   # watch
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ssbl_pb.cli import fail, run

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "vector_ff.yaml", help="YAML config")
    ap.add_argument("--obs-mode", choices=["vector", "camera", "camera_speed"])
    ap.add_argument("--encoder", choices=["none", "cnn", "conv", "saev"])
    ap.add_argument("--policy", choices=["ff", "lstm"], help="ff = PPO, lstm = RecurrentPPO")
    ap.add_argument("--scenario", help="default | mixed | behind | FORMATION[-N] | a,b,...")
    ap.add_argument("--n-envs", type=int, help="parallel environments")
    ap.add_argument("--vec-env", choices=["auto", "batched", "dummy", "subproc"],
                    help="auto (default): batched for the Vector mode (all envs in one array step), else dummy")
    ap.add_argument("--total-steps", type=int)
    ap.add_argument("--seed", type=int)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override any config key, e.g. reward.w_smooth=0.1 or ppo.learning_rate=1e-4")
    ap.add_argument("--out", type=Path, help="run directory (default runs/<name>)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing run directory")
    ap.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue a run from its last checkpoint")
    ap.add_argument("--init-from", type=Path, metavar="RUN_DIR",
                    help="start from another run's final weights (fine-tuning with this config)")
    args = ap.parse_args(argv)

    from ssbl_pb.training.config import parse_overrides
    from ssbl_pb.training.run import ConfigError, RunError, load_config, resume, train

    try:
        if args.resume:
            summary = resume(args.resume, args.total_steps)
            out = args.resume
        else:
            over = {k: v for k, v in {"obs_mode": args.obs_mode, "encoder": args.encoder, "policy": args.policy,
                                      "scenario": args.scenario, "n_envs": args.n_envs, "vec_env": args.vec_env,
                                      "total_steps": args.total_steps, "seed": args.seed}.items() if v is not None}
            over.update(parse_overrides(args.set))
            cfg = load_config(args.config, over)
            out = args.out or ROOT / "runs" / cfg.name
            summary = train(cfg, out, args.overwrite, args.init_from)
    except (ConfigError, RunError, ValueError, FileNotFoundError) as exc:
        return fail(exc)
    best = summary.get("best_eval") or {}
    print(f"{summary['steps']} steps in {summary['wall_time_s']} s ({summary['steps_per_s']} steps/s); best eval "
          f"success {best.get('success_rate', float('nan')):.0%} -> {out}")
    return 0


if __name__ == "__main__":
    run(main)
