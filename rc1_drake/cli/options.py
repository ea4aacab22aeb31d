"""Option types and helpers every command shares: one-line argparse errors, NAME=VALUE values, the model and
campaign a command takes, output checks."""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import tempfile
from pathlib import Path

from ..config import (
    FRICTION_NAMES,
    SERVO_NAMES,
    START_MODES,
    Failure,
    Friction,
    Rc1Error,
    Scenario,
)
from ..scenarios import ModelFile, load_model_file, load_scenario, validate


class Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(2, f"{self.prog}: error: {message}\n")


NAMED_MODEL = (
    "; FILE:NAME takes scenario NAME of a file of named scenarios (e.g. scenarios/paper_findings.yaml:nominal)"
)


def add_model_file(parser, help: str, *, aliases=(), dest: str = "model_file", metavar: str = "PATH") -> None:
    """`--model-file` of a command: a model file, or FILE:NAME for a scenario of a file of named scenarios."""
    parser.add_argument("--model-file", *aliases, dest=dest, type=Path, metavar=metavar, help=help + NAMED_MODEL)


def named_value(known, what: str, form: str):
    """An argparse type for FORM=VALUE with the name among `known` (what it names, for the one-line error)."""

    def parse(text: str) -> tuple[str, float]:
        name, sep, value = text.partition("=")
        if not sep:
            raise argparse.ArgumentTypeError(f"'{text}' is not {form}")
        if name not in known:
            raise argparse.ArgumentTypeError(f"unknown {what} '{name}' (known: {', '.join(known)})")
        try:
            return name, float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{value}' is not a number (in {text})") from None

    return parse


friction_override = named_value(FRICTION_NAMES, "friction coefficient", "NAME=VALUE")


servo_override = named_value(SERVO_NAMES, "servo gain", "KEY=VALUE")


def html_path(text: str) -> Path:
    if not text.lower().endswith((".html", ".htm")):
        raise argparse.ArgumentTypeError(f"{text}: the animation is written as HTML: give a path ending in .html")
    return Path(text)


def joint_arg(text: str) -> int:
    try:
        j = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a joint number 1..13") from None
    if not 1 <= j <= 13:
        raise argparse.ArgumentTypeError(f"joint {j} does not exist (joints are 1..13)")
    return j


def float_arg(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None


def non_negative(text: str) -> float:
    value = float_arg(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number >= 0")
    return value


def add_checkpoint(parser, *, default: str) -> None:
    parser.add_argument(
        "--checkpoint",
        type=Path,
        metavar="DIR",
        help="keep every replay's result here as it arrives, so that the same command interrupted and "
        f"run again resumes where it stopped (default: out/checkpoints/{default}; removed when "
        "it finishes)",
    )


def add_start_rates(parser, *, default: str, fit: str) -> None:
    parser.add_argument(
        "--start-rates",
        choices=START_MODES,
        default=default,
        help=f"the head's velocity and yaw rate at t = 0 of a trial that does not give them: fit "
        f"({fit}) or rest (the synthetic campaigns' convention: centre of mass at rest, mean "
        f"axis not turning) (default: {default})",
    )


def add_outputs(parser, *, out_help: str) -> None:
    """The options that identify and diagnose share: where results go, and what runs them."""
    parser.add_argument("--json", type=Path, metavar="PATH")
    parser.add_argument("--plots", type=Path, metavar="DIR")
    parser.add_argument("--out", type=Path, metavar="MODEL.yaml", help=out_help)
    parser.add_argument("--workers", type=positive_int, metavar="N", help="local processes (default: every core)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def candidates_arg(text: str) -> list:
    from ..effects import candidate_names

    names = [n.strip() for n in text.split(",") if n.strip()]
    try:
        candidate_names(names)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return names


def joint_list_arg(text: str) -> list:
    joints = []
    for part in text.split(","):
        lo, sep, hi = part.partition("-")
        try:
            span = range(int(lo), int(hi) + 1) if sep else [int(lo)]
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a joint list such as 1-13 or 2,7,13") from None
        for j in span:
            if not 1 <= j <= 13:
                raise argparse.ArgumentTypeError(f"joint {j} does not exist (joints are 1..13)")
            joints.append(j)
    return sorted(set(joints))


def whole_number(text: str, least: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if n < least:
        raise argparse.ArgumentTypeError(f"{n} must be at least {least}")
    return n


def positive_int(text: str) -> int:
    return whole_number(text, 1)


def count_arg(text: str) -> int:
    return whole_number(text, 0)


def effect_arg(text: str) -> tuple[str, float]:
    from ..effects import parse_effect

    try:
        return parse_effect(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def scenario_from_args(args):
    scenario = load_scenario(args.scenario, filename=args.scenarios_file)
    failures = scenario.failures + [Failure(joint=j) for j in args.failed_joint]
    gait = scenario.gait
    if args.bias_deg is not None:
        gait = dataclasses.replace(gait, bias_deg=args.bias_deg)
    if args.phase_step_deg is not None:
        gait = dataclasses.replace(gait, phase_step_deg=args.phase_step_deg)
    base, effects = scenario.friction, dict(scenario.effects)
    if args.model_file:
        model = load_model_file(args.model_file)
        base, effects = model.friction, {**effects, **model.effects}
    friction = dataclasses.replace(base, **dict(args.friction))
    stop = scenario.stop
    if args.time_limit_s is not None:
        stop = dataclasses.replace(stop, time_limit_s=args.time_limit_s)
    effects = {**effects, **dict(args.effect)}
    scenario = dataclasses.replace(
        scenario, failures=failures, gait=gait, friction=friction, stop=stop, effects=effects
    )
    return validate(scenario, where="command line")


def write_atomically(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    write(tmp)
    os.replace(tmp, path)


def validate_friction(overrides: dict, model_file=None) -> Friction:
    return model_from_args(overrides, model_file)[0]


def model_from_args(overrides: dict, model_file=None) -> tuple:
    """(friction, effects): the model file's (default: the paper's identified friction, no effect) with
    --friction overrides, validated."""
    model = ModelFile() if model_file is None else load_model_file(model_file)
    friction = dataclasses.replace(model.friction, **overrides)
    validate(Scenario(friction=friction), where="command line")
    return friction, model.effects


def loaded_campaign(folder):
    """measurements.load_campaign, with its warnings (once per joint) on stderr; several folders (a list) as one
    campaign (measurements.merged_campaigns)."""
    from ..measurements import merged_campaigns

    folders = folder if isinstance(folder, list) else [folder]
    campaign = merged_campaigns(folders)
    for line in campaign.warnings():
        print(f"warning: {', '.join(map(str, folders))}: {line}", file=sys.stderr)
    return campaign


def jsonable(value):
    import numpy as np

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return str(value)


def check_outputs(args) -> None:
    """Rc1Error for an output the command could not write, before it does any work (a long diagnosis must not end
    in an unwritable path): the folders of --json and --out, and --plots, are created and written to once."""
    files = {
        "json": True,
        "out": args.command not in ("sweep", "design"),
        "plots": False,
        "checkpoint": False,
        "report": False,
    }  # sweep's and design's --out: a folder
    folders = [
        (f"--{name} {getattr(args, name)}", getattr(args, name).parent if is_file else getattr(args, name))
        for name, is_file in files.items()
        if isinstance(getattr(args, name, None), Path) and args.command != "synthesize"
    ]
    for option, folder in folders:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.NamedTemporaryFile(dir=folder):
                pass
        except OSError as e:
            raise Rc1Error(f"{option}: cannot write there ({e.strerror})") from None
