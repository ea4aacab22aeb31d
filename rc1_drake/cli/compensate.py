"""`rc1 compensate`: automatic bias, heading feedback and reverse driving for failed joints."""

from __future__ import annotations

import json
from pathlib import Path

from ..config import (
    Failure,
    Scenario,
    Stop,
)
from .options import float_arg, joint_list_arg, positive_int, write_atomically


def add_compensate(sub) -> None:
    cmpn = sub.add_parser("compensate", help="bias, heading feedback and reverse driving for failed joints")
    cmpn.add_argument(
        "--joints",
        type=joint_list_arg,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints to compensate, e.g. 2,7,13 (default 1-13)",
    )
    cmpn.add_argument("--json", type=Path, metavar="PATH", help="write every number")
    cmpn.add_argument("--time-limit-s", type=float_arg, default=30.0, metavar="T")
    cmpn.add_argument("--workers", type=positive_int, metavar="N", help="local processes (default: every core)")
    cmpn.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler")


def cmd_compensate(args) -> int:
    from ..compensation import compensation_study
    from ..executor import make_executor

    scenarios = {
        j: Scenario(failures=[Failure(joint=j)], stop=Stop(time_limit_s=args.time_limit_s)) for j in args.joints
    }
    with make_executor(workers=args.workers, scheduler=args.scheduler) as executor:
        futures = {j: executor.submit(compensation_study, s) for j, s in scenarios.items()}
        results = {j: f.result() for j, f in futures.items()}
    print(f"{'joint':<7}{'strategy':<14}{'outcome':<11}{'drift m':>9}{'progress m':>12}{'t s':>7}{'bias deg':>10}")
    for j, by in results.items():
        for name, r in by.items():
            bias = "" if "bias_deg" not in r else f"{r['bias_deg']:.2f}"
            print(
                f"J{j:<6}{name:<14}{r['outcome']:<11}{r['lateral_drift_m']:9.2f}{r['progress_x_m']:12.2f}"
                f"{r['t_final_s']:7.1f}{bias:>10}"
            )
    if args.json:
        write_atomically(
            args.json, lambda p: p.write_text(json.dumps({f"J{j}": r for j, r in results.items()}, indent=2) + "\n")
        )
    return 0
