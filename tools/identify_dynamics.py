"""Identify Pepper's base dynamics from a log of commands and odometry; write RobotParams fields as YAML.

    python tools/identify_dynamics.py LOG.csv --out dyn.yaml          # + dyn.png, dyn.md
    python tools/identify_dynamics.py --simulate LOG.csv --latency 0.12 --tau 0.25   # make a test log

Log format (docs/calibration.md): CSV with t, cmd_vx, cmd_vy, cmd_wz and odom_x, odom_y, odom_yaw (or
odom_vx, odom_vy, odom_wz). Exit code 2 on bad input (missing columns, non-monotonic timestamps, ...).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ssbl_pb.calib import reports
from ssbl_pb.calib.dynamics import identify
from ssbl_pb.calib.dynamics_log import excitation_plan, read_log, simulate_log, write_log
from ssbl_pb.calib.io import check_outputs
from ssbl_pb.cli import ArgumentParser, command_line, int_at_least, run
from ssbl_pb.files import write_yaml
from ssbl_pb.params import RobotParams, from_dict, load_yaml


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("log", type=Path, help="log CSV to read (or to write with --simulate)")
    ap.add_argument("--out", type=Path, help="YAML of RobotParams fields (default: LOG with .yaml)")
    ap.add_argument("--simulate", action="store_true", help="write a synthetic log from HolonomicBase instead")
    ap.add_argument("--latency", type=float, default=0.12, help="--simulate: latency_s")
    ap.add_argument("--tau", type=float, default=0.25, help="--simulate: time_constant_s")
    ap.add_argument("--accel", type=float, default=0.4, help="--simulate: max_accel")
    ap.add_argument("--speed", type=float, default=0.3, help="--simulate: max_speed")
    ap.add_argument("--dt", type=float, default=0.02, help="--simulate: log period (s)")
    ap.add_argument("--noise", type=float, default=0.001, help="--simulate: odometry position noise (m)")
    ap.add_argument("--seed", type=int_at_least(0), default=0)
    ap.add_argument("--truth", type=Path, help="YAML of the true RobotParams fields (--simulate writes "
                    "LOG.truth.yaml); the report then lists the errors")
    args = ap.parse_args(argv)
    command = command_line("tools/identify_dynamics.py", argv)
    if args.simulate:
        check_outputs(args.log, (".truth.yaml",), "LOG")
        truth = RobotParams(latency_s=args.latency, time_constant_s=args.tau, max_accel=args.accel,
                            max_speed=args.speed, max_yaw_rate=0.8, max_yaw_accel=1.2)
        cmd = excitation_plan(truth, args.dt, args.seed)
        t, pose = simulate_log(truth, cmd, args.dt, args.noise, 2 * args.noise, args.seed + 1)
        write_log(args.log, t, cmd, pose)
        fields = ("latency_s", "time_constant_s", "max_speed", "max_accel", "max_yaw_rate", "max_yaw_accel")
        write_yaml(args.log.with_suffix(".truth.yaml"), {f: getattr(truth, f) for f in fields},
                   header=f"{command}\ntrue parameters of the simulated log {args.log}")
        print(f"{args.log}: {len(t)} rows, {t[-1]:.1f} s")
        return 0
    out = args.out or args.log.with_suffix(".yaml")
    check_outputs(out, (".png", ".md"), "--out" if args.out else "--out (default: LOG with .yaml)")
    log = read_log(args.log)
    truth = None
    if args.truth:  # checked as RobotParams fields (numbers), before any work
        truth = load_yaml(args.truth)
        from_dict(RobotParams, truth, str(args.truth))
    res = identify(log, progress=True)
    params = from_dict(RobotParams, res.params, f"RobotParams identified from {args.log}")
    write_yaml(out, res.params, header=f"{command}\nRobotParams fields identified from {args.log}")
    reports.dynamics_figure(log, res, params, out.with_suffix(".png"))
    reports.write_markdown(out.with_suffix(".md"), reports.dynamics_markdown(log, res, command, truth))
    print(f"{out}: " + ", ".join(f"{k} {v:.4f}" for k, v in res.params.items()))
    for note in res.notes:
        print(f"note: {note}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    run(main)
