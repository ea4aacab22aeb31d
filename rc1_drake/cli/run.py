"""`rc1 run`: one scenario, its summary, JSON, plot and animation."""

from __future__ import annotations

import json
from pathlib import Path

from ..config import (
    FRICTION_NAMES,
)
from ..engine import make_session
from ..scenarios import DEFAULT_SCENARIOS
from .options import (
    add_model_file,
    effect_arg,
    float_arg,
    friction_override,
    html_path,
    joint_arg,
    scenario_from_args,
    write_atomically,
)


def add_run(sub) -> None:
    run = sub.add_parser("run", help="simulate one scenario: summary, JSON, plot")
    run.add_argument("--scenario", default="nominal", help="scenario name (default: nominal)")
    run.add_argument(
        "--scenarios-file",
        type=Path,
        default=DEFAULT_SCENARIOS,
        help=f"YAML file of named scenarios (default: {DEFAULT_SCENARIOS.name} in scenarios/)",
    )
    run.add_argument(
        "--failed-joint",
        type=joint_arg,
        action="append",
        default=[],
        metavar="J",
        help="power joint J off from t = 0 (repeatable)",
    )
    run.add_argument("--bias-deg", type=float_arg, metavar="B", help="bias B_i on every joint (Eq. 7), degrees")
    run.add_argument("--phase-step-deg", type=float_arg, metavar="P", help="phase step between joints, degrees")
    run.add_argument(
        "--friction",
        type=friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"set a friction coefficient ({', '.join(FRICTION_NAMES)}); repeatable",
    )
    add_model_file(
        run,
        "a model file (friction and effects), e.g. from rc1 identify --out or rc1 diagnose",
        aliases=("--friction-file",),
    )
    run.add_argument(
        "--effect",
        type=effect_arg,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect (EFFECT=VALUE or PARAMETER=VALUE, see rc1 effects); repeatable",
    )
    run.add_argument("--time-limit-s", type=float_arg, metavar="T", help="stop after T seconds at the latest")
    run.add_argument("--json", type=Path, metavar="PATH", help="write the summary as JSON")
    run.add_argument("--plot", type=Path, metavar="PATH", help="write the head path figure (PNG, PDF, SVG)")
    run.add_argument(
        "--animate",
        type=html_path,
        metavar="PATH.html",
        help="write a standalone HTML animation of the run (Meshcat, plays offline in a browser)",
    )


def cmd_run(args) -> int:
    from ..metrics import summarize

    scenario = scenario_from_args(args)
    run = make_session(scenario, engine=args.engine).simulate(scenario)
    summary = summarize(run)
    record = {"scenario": args.scenario, "failed_joints": scenario.failed_joints, **summary.to_json()}
    width = max(map(len, record))
    for key, value in record.items():
        print(f"{key:<{width}}  {value}")
    if args.json:
        write_atomically(args.json, lambda p: p.write_text(json.dumps(record, indent=2) + "\n"))
    if args.plot:
        from ..plots import head_path_figure

        title = f"{args.scenario}: failed joints {scenario.failed_joints or 'none'} - {summary.outcome}"
        fig = head_path_figure([run], title=title)
        write_atomically(args.plot, lambda p: fig.savefig(p, format=args.plot.suffix.lstrip(".") or "png", dpi=120))
    if args.animate:
        from ..animate import write_animation

        print(f"animation: {write_animation(run, args.animate)}")
    return 0
