#!/usr/bin/env python
"""Train an approaching policy with PPO (feed-forward) or RecurrentPPO (LSTM).

Examples:
    python tools/train_pb.py                                   # configs/vector_ff.yaml defaults
    python tools/train_pb.py --config configs/vector_lstm.yaml --total-steps 200000
    python tools/train_pb.py --scenario mixed --out runs/mixed --set reward.w_smooth=0.1
    python tools/train_pb.py --resume runs/ppo_vector          # continue a killed run
    python tools/train_pb.py --recipe configs/recipes/vector.yaml --seed 1   # the shipped policy's stages, in one
    tensorboard --logdir runs/                                   # watch
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ssbl_pb.cli import ArgumentParser, fail, int_at_least, int_in, run
from ssbl_pb.training.config import SEED_MAX, load_config, parse_overrides, run_name

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__)
    ap.add_argument("--config", type=Path, help="YAML config (default: configs/vector_ff.yaml, vector_lstm.yaml "
                    "with --policy lstm, camera_cnn.yaml with a camera --obs-mode)")
    ap.add_argument("--obs-mode", choices=["vector", "camera", "camera_speed"])
    ap.add_argument("--encoder", choices=["none", "cnn", "conv", "saev"])
    ap.add_argument("--policy", choices=["ff", "lstm"], help="ff = PPO, lstm = RecurrentPPO")
    ap.add_argument("--scenario", help="default | mixed | behind | FORMATION[-N] | a,b,...; each may end in "
                    "@empty, @furnished or @map (the --room-yaml room)")
    ap.add_argument("--n-envs", type=int, help="parallel environments")
    ap.add_argument("--vec-env", choices=["auto", "batched", "dummy", "subproc"],
                    help="auto (default): batched for the Vector mode (all envs in one array step), else dummy")
    ap.add_argument("--total-steps", type=int_at_least(1))
    ap.add_argument("--seed", type=int_in(0, SEED_MAX))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override any config key, e.g. reward.w_smooth=0.1 or ppo.learning_rate=1e-4")
    ap.add_argument("--out", type=Path, help="run directory (default runs/<name>)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing run directory")
    ap.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue a run from its last checkpoint")
    ap.add_argument("--init-from", type=Path, metavar="RUN_DIR",
                    help="start from another run's final weights (fine-tuning with this config)")
    ap.add_argument("--recipe", type=Path, metavar="YAML", help="run a recipe's stages one after another, each "
                    "from the one before (configs/recipes/); the same command continues a stopped recipe; with "
                    "--out (default runs/<name>_recipe) and --seed only")
    args = ap.parse_args(argv)
    if args.recipe:
        return _recipe(args)

    if args.resume:
        if args.overwrite or args.init_from or args.config or args.set:
            return fail("--resume continues a run with its own config; drop --config/--set/--init-from/--overwrite")
        from ssbl_pb.training.run import resume  # lazy: torch and SB3 (~3 s), which --help does without

        summary = resume(args.resume, args.total_steps)
        out = args.resume
    else:
        flags = {"obs_mode": args.obs_mode, "encoder": args.encoder, "policy": args.policy, "scenario": args.scenario,
                 "n_envs": args.n_envs, "vec_env": args.vec_env, "total_steps": args.total_steps, "seed": args.seed}
        over = {k: v for k, v in flags.items() if v is not None}
        over.update(parse_overrides(args.set))
        config = args.config or default_config(args.policy, args.obs_mode)
        cfg = load_config(config, over, env_check=True)
        cfg = run_name(cfg, load_config(config), "name" in over)
        out = args.out or ROOT / "runs" / cfg.name
        from ssbl_pb.training.run import train  # lazy: as above, and a config error comes before them

        summary = train(cfg, out, args.overwrite, args.init_from)
    best = summary.get("best_eval")
    best_text = (f"best eval success {best['success_rate']:.0%}" if best else
                 "no evaluation yet (the run ended before eval_every steps)")
    print(f"{summary['steps']} steps in {summary['wall_time_s']} s ({summary['steps_per_s']} steps/s); {best_text} "
          f"-> {out}")
    return 0


def _recipe(args: Any) -> int:
    from ssbl_pb.training.recipe import load_recipe, run_recipe  # lazy: as above (training.run, torch and SB3)

    given = {"--config": args.config, "--resume": args.resume, "--set": args.set, "--init-from": args.init_from,
             "--overwrite": args.overwrite, "--total-steps": args.total_steps, "--obs-mode": args.obs_mode,
             "--encoder": args.encoder, "--policy": args.policy, "--scenario": args.scenario, "--n-envs": args.n_envs,
             "--vec-env": args.vec_env}
    others = [flag for flag, value in given.items() if value]
    if others:
        return fail(f"--recipe sets every stage itself; drop {', '.join(others)} (only --out and --seed apply)")
    recipe = load_recipe(args.recipe)
    out = args.out or ROOT / "runs" / f"{recipe.name}_recipe"
    record = run_recipe(recipe, out, args.seed)
    print(f"{record['total_steps']} steps in {len(record['stages'])} stages -> {out} (final model: "
          f"{record['final_model']}; learning curve: {out / 'learning_curve.png'})")
    return 0


def default_config(policy: str | None, obs_mode: str | None) -> Path:
    """The shipped config matching ``--policy`` / ``--obs-mode`` when no ``--config`` is given."""
    if obs_mode in ("camera", "camera_speed"):
        return ROOT / "configs" / "camera_cnn.yaml"
    return ROOT / "configs" / ("vector_lstm.yaml" if policy == "lstm" else "vector_ff.yaml")


if __name__ == "__main__":
    run(main)
