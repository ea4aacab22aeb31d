"""The `rc1` command. main() only parses arguments and calls the library."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from pathlib import Path

from .config import DEFAULT_SCENARIOS, FRICTION_NAMES, Failure, Rc1Error, load_scenario, validate


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(2, f"{self.prog}: error: {message}\n")


def _friction_override(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"'{text}' is not NAME=VALUE")
    if name not in FRICTION_NAMES:
        raise argparse.ArgumentTypeError(f"unknown friction coefficient '{name}' (known: {', '.join(FRICTION_NAMES)})")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{value}' is not a number (in {text})") from None


def _joint(text: str) -> int:
    try:
        j = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a joint number 1..13") from None
    if not 1 <= j <= 13:
        raise argparse.ArgumentTypeError(f"joint {j} does not exist (joints are 1..13)")
    return j


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None


def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rc1", description="Simulate the RC1 wheeled snake robot (Drake).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    run = sub.add_parser("run", help="simulate one scenario: summary, JSON, plot")
    run.add_argument("--scenario", default="nominal", help="scenario name (default: nominal)")
    run.add_argument("--scenarios-file", type=Path, default=DEFAULT_SCENARIOS,
                     help=f"YAML file of named scenarios (default: {DEFAULT_SCENARIOS.name} in scenarios/)")
    run.add_argument("--failed-joint", type=_joint, action="append", default=[], metavar="J",
                     help="power joint J off from t = 0 (repeatable)")
    run.add_argument("--bias-deg", type=_float, metavar="B", help="bias B_i on every joint (Eq. 7), degrees")
    run.add_argument("--phase-step-deg", type=_float, metavar="P", help="phase step between joints, degrees")
    run.add_argument("--friction", type=_friction_override, action="append", default=[], metavar="NAME=VALUE",
                     help=f"set a friction coefficient ({', '.join(FRICTION_NAMES)}); repeatable")
    run.add_argument("--time-limit-s", type=_float, metavar="T", help="stop after T seconds at the latest")
    run.add_argument("--json", type=Path, metavar="PATH", help="write the summary as JSON")
    run.add_argument("--plot", type=Path, metavar="PATH", help="write the head path figure (PNG, PDF, SVG)")
    return parser


def scenario_from_args(args):
    scenario = load_scenario(args.scenario, filename=args.scenarios_file)
    failures = scenario.failures + [Failure(joint=j) for j in args.failed_joint]
    gait = scenario.gait
    if args.bias_deg is not None:
        gait = dataclasses.replace(gait, bias_deg=args.bias_deg)
    if args.phase_step_deg is not None:
        gait = dataclasses.replace(gait, phase_step_deg=args.phase_step_deg)
    friction = dataclasses.replace(scenario.friction, **dict(args.friction))
    stop = scenario.stop
    if args.time_limit_s is not None:
        stop = dataclasses.replace(stop, time_limit_s=args.time_limit_s)
    scenario = dataclasses.replace(scenario, failures=failures, gait=gait, friction=friction, stop=stop)
    return validate(scenario, where="command line")


def _write_atomically(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    write(tmp)
    os.replace(tmp, path)


def cmd_run(args) -> int:
    from .metrics import summarize
    from .protocol import simulate

    scenario = scenario_from_args(args)
    run = simulate(scenario=scenario)
    summary = summarize(run)
    record = {"scenario": args.scenario, "failed_joints": scenario.failed_joints, **summary.to_json()}
    width = max(map(len, record))
    for key, value in record.items():
        print(f"{key:<{width}}  {value}")
    if args.json:
        _write_atomically(args.json, lambda p: p.write_text(json.dumps(record, indent=2) + "\n"))
    if args.plot:
        from .plots import head_path_figure

        title = f"{args.scenario}: failed joints {scenario.failed_joints or 'none'} - {summary.outcome}"
        fig = head_path_figure([run], title=title)
        _write_atomically(args.plot, lambda p: fig.savefig(p, format=args.plot.suffix.lstrip(".") or "png", dpi=120))
    return 0


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    try:
        return {"run": cmd_run}[args.command](args)
    except Rc1Error as e:
        print(f"rc1 {args.command}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"rc1 {args.command}: error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
