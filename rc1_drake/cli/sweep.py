"""`rc1 sweep`: no failure and each joint failed in turn, streamed and resumed."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..config import (
    FAILURE_MODES,
    Stop,
)
from ..scenarios import validate
from .options import (
    add_model_file,
    float_arg,
    friction_override,
    joint_list_arg,
    model_from_args,
    positive_int,
    write_atomically,
)


def add_sweep(sub) -> None:
    swp = sub.add_parser("sweep", help="fail each joint in turn (and none), several trials each")
    swp.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="results folder: results.jsonl streams a row per run; rerunning resumes",
    )
    swp.add_argument("--trials", type=positive_int, default=5, metavar="N", help="trials per case (default 5)")
    swp.add_argument(
        "--joints",
        type=joint_list_arg,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints, e.g. 1-13 or 2,7,13 (default 1-13)",
    )
    swp.add_argument("--mode", choices=FAILURE_MODES, default="free", help="failure mode (default free, as the paper)")
    swp.add_argument("--fail-time-s", type=float_arg, default=0.0, metavar="T", help="when the joints fail (default 0)")
    swp.add_argument("--double", action="store_true", help="every pair of the joints instead of one at a time")
    swp.add_argument("--no-nominal", action="store_true", help="leave out the no-failure case")
    swp.add_argument("--friction", type=friction_override, action="append", default=[], metavar="NAME=VALUE")
    add_model_file(swp, "a model file (friction and effects), e.g. from rc1 identify --out")
    swp.add_argument(
        "--friction-spread",
        type=float_arg,
        default=0.0,
        metavar="F",
        help="draw each friction coefficient within +-F (a fraction) of its value per run",
    )
    swp.add_argument("--bias-deg", type=float_arg, default=0.0, metavar="B", help="bias on every joint, degrees")
    swp.add_argument("--time-limit-s", type=float_arg, default=30.0, metavar="T")
    swp.add_argument("--seed", type=int, default=0)
    swp.add_argument("--workers", type=positive_int, metavar="N", help="local processes (default: every core)")
    swp.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def cmd_sweep(args) -> int:
    import matplotlib.pyplot as plt

    from ..executor import make_executor
    from ..plots import paths_grid_figure, sweep_figure
    from ..sweep import (
        double_failure_sets,
        format_table,
        half_summary,
        make_jobs,
        run_sweep,
        single_failure_sets,
        summarize_sweep,
    )

    if args.double:
        sets = ([[]] if not args.no_nominal else []) + double_failure_sets(args.joints, mode=args.mode)
        for s in sets:
            for f in s:
                f.time_s = args.fail_time_s
    else:
        sets = single_failure_sets(
            args.joints, mode=args.mode, time_s=args.fail_time_s, include_none=not args.no_nominal
        )
    friction, effects = model_from_args(dict(args.friction), args.model_file)
    jobs = make_jobs(
        failure_sets=sets,
        trials=args.trials,
        seed=args.seed,
        friction=friction,
        effects=effects,
        friction_spread=args.friction_spread,
        bias_deg=args.bias_deg,
        stop=Stop(time_limit_s=args.time_limit_s),
    )
    for job in jobs[:1] + jobs[-1:]:
        validate(job.scenario, where="command line")
    with make_executor(workers=args.workers, scheduler=args.scheduler) as executor:
        rows = run_sweep(jobs, args.out / "results.jsonl", executor=executor)
    table = summarize_sweep(rows)
    halves = half_summary(table)
    print(format_table(table))
    for name, h in halves.items():
        share = "-" if h["crossed_fraction"] is None else f"{100 * h['crossed_fraction']:.0f}%"
        drift = "-" if h["mean_abs_drift_per_m"] is None else f"{h['mean_abs_drift_per_m']:.3f}"
        print(f"{name}: {h['runs']} runs, {share} reached the line, mean |drift| per metre {drift}")
    errors = [r for r in rows if r["status"] != "ok"]
    for r in errors:
        print(f"error in {r['label']} trial {r['trial']}: {r['error']}", file=sys.stderr)
    write_atomically(
        args.out / "summary.json",
        lambda p: p.write_text(json.dumps({"cases": table, "halves": halves}, indent=2) + "\n"),
    )
    for name, fig in (("outcome_drift.png", sweep_figure(table)), ("paths.png", paths_grid_figure(rows))):
        write_atomically(args.out / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
        plt.close(fig)
    return 0
