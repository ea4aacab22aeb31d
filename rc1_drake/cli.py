"""The `rc1` command. main() only parses arguments and calls the library."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from .config import (
    FAILURE_MODES,
    FRICTION_NAMES,
    SERVO_NAMES,
    START_MODES,
    TRUTH_MODELS,
    Failure,
    Friction,
    Rc1Error,
    Scenario,
    Servo,
    Stop,
)
from .diagnose import INPUT_NOISE_SAMPLES as DIAGNOSE_NOISE_SAMPLES
from .diagnose import THRESHOLDS
from .engine import ENGINES, engine_for, make_session
from .identify import INPUT_NOISE_SAMPLES
from .progress import Counter
from .reproduce import PAPER_TRIALS, TIME_LIMIT_S
from .scenarios import DEFAULT_SCENARIOS, ModelFile, load_model_file, load_scenario, model_to_yaml, validate
from .sysid.evaluate import Checkpoint


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(2, f"{self.prog}: error: {message}\n")


NAMED_MODEL = (
    "; FILE:NAME takes scenario NAME of a file of named scenarios (e.g. scenarios/paper_findings.yaml:nominal)"
)


def _named_value(known, what: str, form: str):
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


_friction_override = _named_value(FRICTION_NAMES, "friction coefficient", "NAME=VALUE")
_servo_override = _named_value(SERVO_NAMES, "servo gain", "KEY=VALUE")


def _html_path(text: str) -> Path:
    if not text.lower().endswith((".html", ".htm")):
        raise argparse.ArgumentTypeError(f"{text}: the animation is written as HTML: give a path ending in .html")
    return Path(text)


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


def _non_negative(text: str) -> float:
    value = _float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number >= 0")
    return value


def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rc1", description="Simulate the RC1 wheeled snake robot (Drake).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in (
        _add_run,
        _add_synthesize,
        _add_compare,
        _add_sweep,
        _add_identify,
        _add_compensate,
        _add_effects,
        _add_diagnose,
        _add_reproduce,
    ):
        add(sub)
    # Every simulating command picks its engine.
    for name, command in sub.choices.items():
        if name == "effects":
            continue
        default = "drake" if name == "run" else "compiled"
        command.add_argument(
            "--engine",
            choices=ENGINES,
            default=default,
            help=f"drake (the Diagram, the model of record) or compiled (its numba twin; "
            f"tests/test_engine.py) (default: {default})",
        )
    return parser


def _add_run(sub) -> None:
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
        type=_joint,
        action="append",
        default=[],
        metavar="J",
        help="power joint J off from t = 0 (repeatable)",
    )
    run.add_argument("--bias-deg", type=_float, metavar="B", help="bias B_i on every joint (Eq. 7), degrees")
    run.add_argument("--phase-step-deg", type=_float, metavar="P", help="phase step between joints, degrees")
    run.add_argument(
        "--friction",
        type=_friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"set a friction coefficient ({', '.join(FRICTION_NAMES)}); repeatable",
    )
    run.add_argument(
        "--model-file",
        "--friction-file",
        dest="model_file",
        type=Path,
        metavar="PATH",
        help="a model file (friction and effects), e.g. from rc1 identify --out or rc1 diagnose" + NAMED_MODEL,
    )
    run.add_argument(
        "--effect",
        type=_effect,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect (EFFECT=VALUE or PARAMETER=VALUE, see rc1 effects); repeatable",
    )
    run.add_argument("--time-limit-s", type=_float, metavar="T", help="stop after T seconds at the latest")
    run.add_argument("--json", type=Path, metavar="PATH", help="write the summary as JSON")
    run.add_argument("--plot", type=Path, metavar="PATH", help="write the head path figure (PNG, PDF, SVG)")
    run.add_argument(
        "--animate",
        type=_html_path,
        metavar="PATH.html",
        help="write a standalone HTML animation of the run (Meshcat, plays offline in a browser)",
    )


def _add_synthesize(sub) -> None:
    syn = sub.add_parser("synthesize", help="write a synthetic campaign in the measurement format")
    syn.add_argument("out", type=Path, help="campaign folder to create (must not exist)")
    syn.add_argument(
        "--design",
        choices=["paper", "identification"],
        default="paper",
        help="paper: its cases, 5 trials each and 1 joint-2 trial; identification: 6 cases of gaits "
        "(70-210 deg/s) and failures, the richest within the servos whose trials replay faithfully",
    )
    syn.add_argument(
        "--trials-per-case",
        type=_positive_int,
        metavar="N",
        help="trials in each case (the paper design's lone joint-2 trial stays one)",
    )
    syn.add_argument("--time-limit-s", type=_float, metavar="T", help="end every trial after T s at the latest")
    syn.add_argument(
        "--friction",
        type=_friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="the truth's friction coefficient (repeatable; default: the paper's identified set)",
    )
    syn.add_argument(
        "--effect",
        type=_effect,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a physical effect in the truth (EFFECT=VALUE or PARAMETER=VALUE, see rc1 effects); repeatable",
    )
    syn.add_argument("--noise-scale", type=_float, default=1.0, metavar="S", help="multiply every sensor noise by S")
    syn.add_argument("--no-camera", action="store_true", help="leave out the overhead camera columns")
    syn.add_argument(
        "--truth-model",
        choices=TRUTH_MODELS,
        default="drake",
        help="drake: this project's Diagram through its servos; reference: the independent planar model "
        "of reference.py (kinematic joints, its own limit model, the head at rest at its start; "
        "effects: wheel_toe only)",
    )
    syn.add_argument("--sample-period-s", type=_float, default=0.01, metavar="DT", help="the sensors' sample period")
    syn.add_argument(
        "--record-after-s",
        type=_float,
        default=0.0,
        metavar="T",
        help="start the recording T s after the robot started (the data then begin in motion)",
    )
    syn.add_argument("--seed", type=int, default=0)
    syn.add_argument("--truth", type=Path, metavar="PATH", help="where to record the truth (JSON)")


def _add_compare(sub) -> None:
    cmp = sub.add_parser("compare", help="replay a campaign through the model and score it (Eq. 6, Table 2)")
    cmp.add_argument("campaign", type=Path, help="campaign folder (data/README.md)")
    cmp.add_argument(
        "--friction",
        type=_friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="friction coefficient for the model (repeatable)",
    )
    cmp.add_argument(
        "--model-file",
        "--friction-file",
        dest="model_file",
        type=Path,
        metavar="PATH",
        help="a model file (friction and effects), e.g. from rc1 identify --out or rc1 diagnose" + NAMED_MODEL,
    )
    cmp.add_argument(
        "--effect",
        type=_effect,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect to the model (see rc1 effects); repeatable",
    )
    cmp.add_argument("--json", type=Path, metavar="PATH", help="write every per-trial and per-case number")
    cmp.add_argument("--plots", type=Path, metavar="DIR", help="write figures in the paper's styles")
    _add_start_rates(cmp, default="rest", fit="to its first 0.5 s of camera path and IMU")
    cmp.add_argument("--workers", type=_positive_int, metavar="N", help="processes (default: every core)")


def _add_sweep(sub) -> None:
    swp = sub.add_parser("sweep", help="fail each joint in turn (and none), several trials each")
    swp.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="results folder: results.jsonl streams a row per run; rerunning resumes",
    )
    swp.add_argument("--trials", type=_positive_int, default=5, metavar="N", help="trials per case (default 5)")
    swp.add_argument(
        "--joints",
        type=_joint_list,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints, e.g. 1-13 or 2,7,13 (default 1-13)",
    )
    swp.add_argument("--mode", choices=FAILURE_MODES, default="free", help="failure mode (default free, as the paper)")
    swp.add_argument("--fail-time-s", type=_float, default=0.0, metavar="T", help="when the joints fail (default 0)")
    swp.add_argument("--double", action="store_true", help="every pair of the joints instead of one at a time")
    swp.add_argument("--no-nominal", action="store_true", help="leave out the no-failure case")
    swp.add_argument("--friction", type=_friction_override, action="append", default=[], metavar="NAME=VALUE")
    swp.add_argument(
        "--model-file",
        type=Path,
        metavar="PATH",
        help="a model file (friction and effects), e.g. from rc1 identify --out" + NAMED_MODEL,
    )
    swp.add_argument(
        "--friction-spread",
        type=_float,
        default=0.0,
        metavar="F",
        help="draw each friction coefficient within +-F (a fraction) of its value per run",
    )
    swp.add_argument("--bias-deg", type=_float, default=0.0, metavar="B", help="bias on every joint, degrees")
    swp.add_argument("--time-limit-s", type=_float, default=30.0, metavar="T")
    swp.add_argument("--seed", type=int, default=0)
    swp.add_argument("--workers", type=_positive_int, metavar="N", help="local processes (default: every core)")
    swp.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def _add_identify(sub) -> None:
    idn = sub.add_parser("identify", help="identify the five friction coefficients from a campaign")
    idn.add_argument("campaign", type=Path)
    idn.add_argument(
        "--method",
        choices=("avs", "program", "equation-error"),
        default="avs",
        help="avs: the paper's Alternating Variable Search; program: least squares of the standardized "
        "residuals, Levenberg-Marquardt steps as MathematicalPrograms solved by SNOPT, started from "
        "what equation error identifies; equation-error: inverse dynamics from camera and "
        "potentiometers, linear least squares, no simulation",
    )
    idn.add_argument("--trials", metavar="IDS", help="comma-separated trial ids to fit (default: all)")
    idn.add_argument(
        "--validation",
        metavar="IDS",
        help="comma-separated held-out trial ids to score the result on (default: the trials not fitted)",
    )
    idn.add_argument(
        "--iterations",
        type=_positive_int,
        default=10,
        metavar="N",
        help="AVS iterations, or the program fit's at most (default 10)",
    )
    idn.add_argument(
        "--input-noise-samples",
        type=_count,
        default=INPUT_NOISE_SAMPLES,
        metavar="K",
        help="resampled replays per trial for the potentiometer noise the replays follow, in the "
        f"screening and the reported intervals (default {INPUT_NOISE_SAMPLES}; 0 leaves it out: "
        "intervals too narrow)",
    )
    idn.add_argument(
        "--start",
        "--model-file",
        dest="start",
        type=Path,
        metavar="MODEL.yaml",
        help="a model file: starting coefficients (default: the paper's manual values; frozen ones "
        "stay at them) and effects, which stay fixed" + NAMED_MODEL,
    )
    idn.add_argument(
        "--freeze",
        action="append",
        default=[],
        choices=FRICTION_NAMES,
        metavar="NAME",
        help="keep a coefficient at its start value (repeatable)",
    )
    _add_start_rates(
        idn,
        default="rest",
        fit="fitted once per trial to its first 0.5 s of camera path and IMU, "
        "at the start model, and held through the fit",
    )
    _add_checkpoint(idn, default="<campaign>-identify")
    _add_outputs(idn, out_help="write a model file: the identified coefficients and the (fixed) effects")


def _add_compensate(sub) -> None:
    cmpn = sub.add_parser("compensate", help="bias, heading feedback and reverse driving for failed joints")
    cmpn.add_argument(
        "--joints",
        type=_joint_list,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints to compensate, e.g. 2,7,13 (default 1-13)",
    )
    cmpn.add_argument("--json", type=Path, metavar="PATH", help="write every number")
    cmpn.add_argument("--time-limit-s", type=_float, default=30.0, metavar="T")
    cmpn.add_argument("--workers", type=_positive_int, metavar="N", help="local processes (default: every core)")
    cmpn.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler")


def _add_effects(sub) -> None:
    sub.add_parser("effects", help="list the candidate physical effects and their parameters")


def _add_diagnose(sub) -> None:
    dgn = sub.add_parser(
        "diagnose",
        help="find the missing physics: fit, where it fails, rank candidate effects, "
        "accept what holds on held-out trials, repeat",
    )
    dgn.add_argument("campaign", type=Path)
    dgn.add_argument(
        "--model-file",
        type=Path,
        metavar="MODEL.yaml",
        help="today's model (friction and effects; default: the paper's identified friction, no effect)" + NAMED_MODEL,
    )
    dgn.add_argument(
        "--candidates",
        type=_candidates,
        metavar="NAMES",
        help="comma-separated effect names or groups to consider: physical (the default), sensor (the "
        "sensor faults), study (issue 41's mechanisms of the J2 circling), or names from rc1 effects",
    )
    dgn.add_argument("--trials", metavar="IDS", help="comma-separated trial ids (default: all)")
    dgn.add_argument(
        "--freeze",
        action="append",
        default=[],
        choices=FRICTION_NAMES,
        metavar="NAME",
        help="keep a friction coefficient at the model's value (repeatable; saves its replays)",
    )
    dgn.add_argument("--rounds", type=_positive_int, default=3, metavar="N", help="effects to add at most (default 3)")
    dgn.add_argument(
        "--discover",
        action="store_true",
        help="when the verdict is unexplained or ambiguous, fit the discrepancy model (sparse terms at the head, "
        "wheels, tail and failed joints), name what survives and add it to the model file",
    )
    dgn.add_argument(
        "--angles",
        action="store_true",
        help="with --discover: fit the working joints' measured angles too, against the model's servos driven by "
        "each trial's command (the servos' tracking error is their load: it shows forces, such as a tether's, that "
        "the kinematic replay cannot; the servos' gains are fitted with the terms)",
    )
    dgn.add_argument(
        "--input-noise-samples",
        type=_positive_int,
        default=DIAGNOSE_NOISE_SAMPLES,
        metavar="K",
        help="noisy replays of each trial's noise-free twin, for the replay's own miss and its input "
        f"noise (default {DIAGNOSE_NOISE_SAMPLES})",
    )
    dgn.add_argument(
        "--failed-joint-scatter",
        type=_non_negative,
        default=THRESHOLDS.max_failed_joint_scatter,
        metavar="STEPS",
        help="the largest trial-to-trial scatter of a failed joint (probe steps of its constant torque, spring and "
        "viscous torque) taken as noise: another model's failed joint swings differently in each trial; beyond "
        f"it the failed joints show a law, not a scatter (default {THRESHOLDS.max_failed_joint_scatter:g}; 0: never)",
    )
    dgn.add_argument(
        "--no-probe-study",
        action="store_true",
        help="do not simulate short probe trials to name the experiment that would see an effect not detectable here",
    )
    _add_start_rates(
        dgn,
        default="rest",
        fit="three nuisance coordinates per trial, fixed by its first 0.5 s in "
        "every fit: for data whose start follows no known convention",
    )
    dgn.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="write DIR/index.html: one self-contained page with the verdict, the waterfall, each round's ranking, "
        "where the model still fails, the model file and the command",
    )
    _add_checkpoint(dgn, default="<campaign>")
    _add_outputs(
        dgn, out_help="write the diagnosed model (friction and accepted effects; default out/<campaign>.model.yaml)"
    )


def _add_reproduce(sub) -> None:
    rep = sub.add_parser(
        "reproduce",
        help="the paper's section 4: no failure, joints 1-13 failed in turn, J7+bias; each finding reproduced or not",
    )
    rep.add_argument(
        "--model-file",
        type=Path,
        metavar="MODEL.yaml",
        help="the model (friction and effects), e.g. from rc1 diagnose (default: the paper's identified friction)"
        + NAMED_MODEL,
    )
    rep.add_argument("--friction", type=_friction_override, action="append", default=[], metavar="NAME=VALUE")
    rep.add_argument(
        "--effect",
        type=_effect,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect to the model (see rc1 effects); repeatable",
    )
    rep.add_argument(
        "--servo",
        type=_servo_override,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"set a working servo's gain ({', '.join(SERVO_NAMES)}; default the model's); repeatable",
    )
    rep.add_argument(
        "--joints",
        type=_joint_list,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints, e.g. 2,7 (default 1-13); no failure always runs, J7+bias with 7",
    )
    rep.add_argument(
        "--trials",
        type=_positive_int,
        default=PAPER_TRIALS,
        metavar="N",
        help=f"trials per case (default {PAPER_TRIALS}, as the paper)",
    )
    rep.add_argument(
        "--time-limit-s",
        type=_float,
        default=TIME_LIMIT_S,
        metavar="T",
        help=f"end a run that neither reached the line nor circled twice after T s (default {TIME_LIMIT_S:g}: "
        "long enough for a circle up to about 3.5 m across)",
    )
    rep.add_argument("--json", type=Path, metavar="PATH", help="write every case, trial and finding")
    rep.add_argument("--plots", type=Path, metavar="DIR", help="write figures in the style of the paper's Figs. 8-13")
    rep.add_argument("--workers", type=_positive_int, metavar="N", help="local processes (default: every core)")
    rep.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def _add_checkpoint(parser, *, default: str) -> None:
    parser.add_argument(
        "--checkpoint",
        type=Path,
        metavar="DIR",
        help="keep every replay's result here as it arrives, so that the same command interrupted and "
        f"run again resumes where it stopped (default: out/checkpoints/{default}; removed when "
        "it finishes)",
    )


def _add_start_rates(parser, *, default: str, fit: str) -> None:
    parser.add_argument(
        "--start-rates",
        choices=START_MODES,
        default=default,
        help=f"the head's velocity and yaw rate at t = 0 of a trial that does not give them: fit "
        f"({fit}) or rest (the synthetic campaigns' convention: centre of mass at rest, mean "
        f"axis not turning) (default: {default})",
    )


def _add_outputs(parser, *, out_help: str) -> None:
    """The options that identify and diagnose share: where results go, and what runs them."""
    parser.add_argument("--json", type=Path, metavar="PATH")
    parser.add_argument("--plots", type=Path, metavar="DIR")
    parser.add_argument("--out", type=Path, metavar="MODEL.yaml", help=out_help)
    parser.add_argument("--workers", type=_positive_int, metavar="N", help="local processes (default: every core)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def _candidates(text: str) -> list:
    from .effects import candidate_names

    names = [n.strip() for n in text.split(",") if n.strip()]
    try:
        candidate_names(names)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return names


def _joint_list(text: str) -> list:
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


def _whole_number(text: str, least: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if n < least:
        raise argparse.ArgumentTypeError(f"{n} must be at least {least}")
    return n


def _positive_int(text: str) -> int:
    return _whole_number(text, 1)


def _count(text: str) -> int:
    return _whole_number(text, 0)


def _effect(text: str) -> tuple[str, float]:
    from .effects import parse_effect

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


def _write_atomically(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    write(tmp)
    os.replace(tmp, path)


def cmd_run(args) -> int:
    from .metrics import summarize

    scenario = scenario_from_args(args)
    run = make_session(scenario, engine=args.engine).simulate(scenario)
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
    if args.animate:
        from .animate import write_animation

        print(f"animation: {write_animation(run, args.animate)}")
    return 0


def cmd_synthesize(args) -> int:
    from .synthesize import DESIGNS, Noise, synthesize_campaign

    if args.out.exists():
        raise Rc1Error(f"{args.out}: already exists; synthesize writes a new campaign folder")
    design = DESIGNS[args.design]
    if args.trials_per_case:
        design = [
            dataclasses.replace(c, trials=args.trials_per_case if c.trials > 1 or args.design != "paper" else c.trials)
            for c in design
        ]
    stop = None if args.time_limit_s is None else Stop(time_limit_s=args.time_limit_s)
    friction = validate_friction(dict(args.friction))
    effects = dict(args.effect)
    validate(Scenario(effects=effects, stop=stop or Stop()), where="command line")
    campaign = synthesize_campaign(
        args.out,
        design=design,
        friction=friction,
        effects=effects,
        noise=Noise().scaled(args.noise_scale),
        camera=not args.no_camera,
        seed=args.seed,
        truth_file=args.truth,
        stop=stop,
        truth_model=args.truth_model,
        sample_period_s=args.sample_period_s,
        record_after_s=args.record_after_s,
    )
    print(f"wrote {len(campaign.trials)} trials to {args.out}" + (f"; truth in {args.truth}" if args.truth else ""))
    return 0


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
    """measurements.load_campaign, with its warnings (once per joint) on stderr."""
    from .measurements import load_campaign

    campaign = load_campaign(folder)
    for line in campaign.warnings():
        print(f"warning: {folder}: {line}", file=sys.stderr)
    return campaign


def cmd_compare(args) -> int:
    from .compare import compare_campaign

    campaign = loaded_campaign(args.campaign)
    friction, effects = model_from_args(dict(args.friction), args.model_file)
    effects = {**effects, **dict(args.effect)}
    validate(Scenario(effects=effects), where="command line")

    progress = Counter("replayed trials:")
    report = compare_campaign(
        campaign, friction, effects=effects or None, workers=args.workers, progress=progress, start=args.start_rates
    )
    progress.close()
    print(f"Simulator error (paper Eq. 6) per trial, {campaign.path}:")
    print(report.table())
    print()
    print(f"{'trial':<16}{'case':<10}{'Eq.6 %':>8}{'yaw-rate fit %':>16}{'camera x/y fit %':>18}{'outcome':>11}")
    for r in report.trials:
        cam = "-" if r.camera_fit_pct is None else f"{r.camera_fit_pct['x']:.0f}/{r.camera_fit_pct['y']:.0f}"
        print(f"{r.trial_id:<16}{r.case:<10}{r.eq6_error_pct:8.1f}{r.yaw_rate_fit_pct:16.1f}{cam:>18}{r.outcome:>11}")
        if r.circle_diameter_model_m is not None or r.circle_diameter_measured_m is not None:
            print(
                f"{'':<16}revolutions model {r.revolutions_model:.2f} / measured {r.revolutions_measured:.2f}; "
                f"circle diameter model {r.circle_diameter_model_m} / measured {r.circle_diameter_measured_m}"
            )
    from .residuals import where_it_fails

    where = where_it_fails(report, campaign)
    print()
    print(
        "Where the model fails (worst first; path error from the camera; LB p: whiteness of the yaw-rate "
        "residual, small = structure left; the feature it correlates with most):"
    )
    print(where.table())
    if args.json:
        record = {**report.to_json(), "where_it_fails": where.to_json()}
        _write_atomically(args.json, lambda p: p.write_text(json.dumps(record, indent=2) + "\n"))
    if args.plots:
        write_compare_plots(report, campaign, args.plots)
    return 0


def write_compare_plots(report, campaign, folder: Path) -> None:
    import matplotlib.pyplot as plt

    from .plots import compare_figures

    for case_figures in compare_figures(report, campaign).values():
        for filename, fig in case_figures.items():
            _write_atomically(folder / filename, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
            plt.close(fig)


def cmd_sweep(args) -> int:
    import matplotlib.pyplot as plt

    from .executor import make_executor
    from .plots import paths_grid_figure, sweep_figure
    from .sweep import (
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
    _write_atomically(
        args.out / "summary.json",
        lambda p: p.write_text(json.dumps({"cases": table, "halves": halves}, indent=2) + "\n"),
    )
    for name, fig in (("outcome_drift.png", sweep_figure(table)), ("paths.png", paths_grid_figure(rows))):
        _write_atomically(args.out / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
        plt.close(fig)
    return 0


def cmd_identify(args) -> int:
    import matplotlib.pyplot as plt

    from .identify import avs_figure, friction_to_yaml, identify

    def ids(text):
        return None if not text else [t.strip() for t in text.split(",") if t.strip()]

    def progress(done, total, name, error):
        print(f"  iteration {done}/{total}: {name}, mean Eq. 6 error {error:.2f}%", file=sys.stderr, flush=True)

    campaign = loaded_campaign(args.campaign)
    checkpoint = args.checkpoint or Path("out") / "checkpoints" / f"{Path(campaign.path).name}-identify"
    start = load_model_file(args.start) if args.start else None
    # Where the fit goes as it ends, before its uncertainty: the outputs asked for, else beside the checkpoint.
    fit_model, fit_json = args.out or checkpoint / "fit.model.yaml", args.json or checkpoint / "fit.json"

    def keep_fit(fit):
        _write_atomically(fit_model, lambda p: p.write_text(friction_to_yaml(fit.friction, start and start.effects)))
        record = {"stage": "fit (its uncertainty and held-out errors not computed yet)", **fit.to_json()}
        _write_atomically(fit_json, lambda p: p.write_text(json.dumps(record, indent=2, default=float) + "\n"))
        args.kept += [f"the fitted model in {fit_model}", f"the fit in {fit_json}"]
        print(f"  fit done: {fit_model}, {fit_json}; now its uncertainty", file=sys.stderr, flush=True)

    result = identify(
        campaign,
        method=args.method,
        trials=ids(args.trials),
        validation=ids(args.validation),
        start=start,
        freeze=args.freeze,
        start_rates=args.start_rates,
        iterations=args.iterations,
        input_noise_samples=args.input_noise_samples,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=progress,
        checkpoint=checkpoint,
        on_fit=keep_fit,
    )
    print(result.format())
    if args.json:
        _write_atomically(
            args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2, default=float) + "\n")
        )
    if args.out:
        _write_atomically(args.out, lambda p: p.write_text(friction_to_yaml(result.friction, result.effects)))
    if args.plots and args.method == "avs":
        fig = avs_figure(result.result)
        _write_atomically(args.plots / "avs_iterations.png", lambda p: fig.savefig(p, format="png", dpi=110))
        plt.close(fig)
    for path in {fit_model, fit_json} - {args.out, args.json}:  # kept for a failure; the report has them now
        path.unlink(missing_ok=True)
    Checkpoint.discard(checkpoint)
    return 0


def cmd_compensate(args) -> int:
    from .compensation import compensation_study
    from .config import Scenario
    from .executor import make_executor

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
        _write_atomically(
            args.json, lambda p: p.write_text(json.dumps({f"J{j}": r for j, r in results.items()}, indent=2) + "\n")
        )
    return 0


def cmd_effects(args) -> int:
    from .discrepancy import GROUPS, JOINT_KINDS, SITE_KINDS
    from .effects import LIBRARY

    for effect in (e for e in LIBRARY.values() if not e.discrepancy):
        notes = [] if effect.seen_in_replay else ["gait-driven runs only"]
        notes += [] if effect.default_candidate else ["study: a diagnosis candidate when asked for, --candidates study"]
        print(f"{effect.name}: {effect.summary}" + (f" ({'; '.join(notes)})" if notes else ""))
        for p in effect.parameters:
            print(
                f"    {p.key:<30} [{p.lower:g}, {p.upper:g}]"
                + ("" if p.fitted else f"  setting, default {p.default:g}")
            )
    sites, joints = ", ".join(k for k, _, _ in SITE_KINDS), ", ".join(k for k, _, _ in JOINT_KINDS)
    print(
        "discrepancy terms (rc1 diagnose --discover; keys discrepancy_<where>_<kind>_<unit>): at "
        f"{', '.join(GROUPS)}: {sites}; at failed_joint: {joints}"
    )
    return 0


def cmd_diagnose(args) -> int:
    import matplotlib.pyplot as plt

    from .diagnose import diagnose
    from .plots import candidates_figure, waterfall_figure

    if args.angles and not args.discover:
        raise Rc1Error("--angles fits the angles in discovery: give it with --discover")
    campaign = loaded_campaign(args.campaign)
    model = load_model_file(args.model_file) if args.model_file else ModelFile(friction=Friction())
    trials = None if not args.trials else [t.strip() for t in args.trials.split(",") if t.strip()]
    started = time.perf_counter()
    checkpoint = args.checkpoint or Path("out") / "checkpoints" / Path(campaign.path).name

    def progress(text):
        print(f"  [{time.perf_counter() - started:5.0f} s] {text}", file=sys.stderr, flush=True)

    out = args.out or Path("out") / f"{Path(campaign.path).name}.model.yaml"

    def keep_round(friction, effects, accepted):
        note = f"rc1 diagnose {campaign.path}: after accepting {', '.join(accepted)} (the diagnosis went on)"
        _write_atomically(out, lambda p: p.write_text(model_to_yaml(friction, effects, comment=note)))
        args.kept[:] = [f"the model after accepting {', '.join(accepted)} in {out}"]
        progress(f"model so far written to {out}")

    result = diagnose(
        campaign,
        friction=model.friction,
        effects=model.effects,
        candidates=args.candidates,
        trials=trials,
        held=args.freeze,
        workers=args.workers,
        scheduler=args.scheduler,
        input_noise_samples=args.input_noise_samples,
        max_rounds=args.rounds,
        probe_study=not args.no_probe_study,
        progress=progress,
        start_rates=args.start_rates,
        checkpoint=checkpoint,
        on_round=keep_round,
        thresholds=dataclasses.replace(THRESHOLDS, max_failed_joint_scatter=args.failed_joint_scatter),
    )
    print(result.format())
    note = f"rc1 diagnose {campaign.path}: {result.verdict}"
    _write_atomically(out, lambda p: p.write_text(model_to_yaml(result.friction, result.effects, comment=note)))
    resumed = f", {result.resumed} of them from an interrupted run's checkpoint" if result.resumed else ""
    print(f"model file: {out}  ({result.simulations} simulations{resumed}, {result.wall_s:.0f} s)")
    if args.json:
        _write_atomically(
            args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2, default=_jsonable) + "\n")
        )
    if args.report:
        from .diagnose.page import report_page

        page = report_page(result, campaign, model_yaml=out.read_text(), command=args.command_line)
        _write_atomically(args.report / "index.html", lambda p: p.write_text(page))
        print(f"report: {args.report / 'index.html'}")
    if args.plots:
        write_compare_plots(result.report, campaign, args.plots / "where_it_fails")
        for name, fig in {
            "waterfall.png": waterfall_figure(result.waterfall),
            "candidates.png": candidates_figure(result.candidates),
        }.items():
            _write_atomically(args.plots / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
            plt.close(fig)
    if args.discover:  # last: whatever befalls it, the diagnosis's results are written
        args.kept[:] = [f"the diagnosis's model in {out}"]
        _discover_after(args, result, out, note, progress)
    Checkpoint.discard(checkpoint)
    return 0


def _discover_after(args, result, out: Path, note: str, progress) -> None:
    """rc1 diagnose --discover: the discrepancy model fitted where the verdict left something to explain, its terms
    added to the model file."""
    if result.verdict not in ("unexplained", "ambiguous"):
        print(f"discovery: not run (the verdict is {result.verdict}: nothing left to explain)")
        return
    from .diagnose.discover import discover_campaign

    found = discover_campaign(
        result.trials, result.friction, result.effects, workers=args.workers, scheduler=args.scheduler,
        progress=progress, angles=args.angles,
    )  # fmt: skip
    print(found.format())
    if found.terms:
        note += f"; discovered {', '.join(t.key for t in found.terms)}"
        _write_atomically(out, lambda p: p.write_text(model_to_yaml(result.friction, found.effects, comment=note)))
        print(f"model file with the discovered terms: {out}")


def cmd_reproduce(args) -> int:
    import matplotlib.pyplot as plt

    from .reproduce import reproduce

    friction, effects = model_from_args(dict(args.friction), args.model_file)
    effects = {**effects, **dict(args.effect)}
    named = load_model_file(args.model_file).servo if args.model_file else None
    servo = dataclasses.replace(named or Servo(), **dict(args.servo))
    validate(Scenario(effects=effects, servo=servo, stop=Stop(time_limit_s=args.time_limit_s)), where="command line")

    progress = Counter("ran trials:")
    result = reproduce(
        friction=friction,
        effects=effects,
        servo=servo,
        joints=args.joints,
        trials=args.trials,
        workers=args.workers,
        scheduler=args.scheduler,
        time_limit_s=args.time_limit_s,
        progress=progress,
    )
    progress.close()
    print(result.format())
    print(f"({sum(len(c.trials) for c in result.cases.values())} runs, {result.settings['wall_s']:.0f} s)")
    if args.json:
        _write_atomically(args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2) + "\n"))
    if args.plots:
        figures = {"findings.png": result.figure(), "cases.png": result.figure(cases=tuple(result.cases))}
        for name, fig in figures.items():
            _write_atomically(args.plots / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
            plt.close(fig)
    return 0


def _jsonable(value):
    import numpy as np

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return str(value)


def _check_outputs(args) -> None:
    """Rc1Error for an output the command could not write, before it does any work (a long diagnosis must not end
    in an unwritable path): the folders of --json and --out, and --plots, are created and written to once."""
    files = {
        "json": True,
        "out": args.command != "sweep",
        "plots": False,
        "checkpoint": False,
        "report": False,
    }  # sweep's --out: a folder
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


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    args.command_line = "rc1 " + " ".join(sys.argv[1:] if argv is None else argv)
    args.kept = []  # what a long command has written so far: named if it fails later
    engine = getattr(args, "engine", None)
    with engine_for(engine) if engine else contextlib.nullcontext():  # batch work and its workers follow it
        return _dispatch(args)


def _dispatch(args) -> int:
    """The parsed command, its errors as one line (an unforeseen one's traceback in a log)."""
    try:
        _check_outputs(args)
        return {
            "run": cmd_run,
            "synthesize": cmd_synthesize,
            "compare": cmd_compare,
            "sweep": cmd_sweep,
            "identify": cmd_identify,
            "compensate": cmd_compensate,
            "effects": cmd_effects,
            "diagnose": cmd_diagnose,
            "reproduce": cmd_reproduce,
        }[args.command](args)
    except Rc1Error as e:
        print(f"rc1 {args.command}: error: {e}{_kept(args)}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"rc1 {args.command}: error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rc1 {args.command}: interrupted{_kept_and_resume(args)}", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - anything unforeseen: one line, the traceback in a log
        log = _write_log(args)
        print(
            f"rc1 {args.command}: internal error: {type(e).__name__}: {_first_line(e)}{_kept_and_resume(args)}; "
            f"full log: {log}",
            file=sys.stderr,
        )
        return 1


def _first_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return text if len(text) <= 200 else text[:197] + "..."


def _kept(args) -> str:
    """What a long command had written before it stopped."""
    return f"; kept: {', '.join(args.kept)}" if args.kept else ""


def _kept_and_resume(args) -> str:
    """What the command had written, and how to go on from its checkpoint."""
    kept = _kept(args)
    resumes = args.command in ("identify", "diagnose", "sweep")
    return kept + ("; run the same command again to resume from its checkpoint" if resumes else "")


def _write_log(args) -> Path:
    """The traceback of the exception being handled and the command line, in out/logs (else the temporary folder)."""
    import traceback

    text = f"{args.command_line}\n{time.strftime('%Y-%m-%d %H:%M:%S')}\n\n{traceback.format_exc()}"
    name = f"rc1-{args.command}-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.log"
    for folder in (Path("out") / "logs", Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)
            return folder / name
        except OSError:
            continue
    return Path("(no log: nowhere to write it)")


if __name__ == "__main__":
    sys.exit(main())
