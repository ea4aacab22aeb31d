"""`rc1 reproduce`: the paper's section-4 findings, each marked reproduced or not."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ..config import (
    SERVO_NAMES,
    Scenario,
    Servo,
    Stop,
)
from ..progress import Counter
from ..reproduce import PAPER_TRIALS, TIME_LIMIT_S
from ..scenarios import load_model_file, validate
from .options import (
    add_model_file,
    effect_arg,
    float_arg,
    friction_override,
    joint_list_arg,
    model_from_args,
    positive_int,
    servo_override,
    write_atomically,
)


def add_reproduce(sub) -> None:
    rep = sub.add_parser(
        "reproduce",
        help="the paper's section 4: no failure, joints 1-13 failed in turn, J7+bias; each finding reproduced or not",
    )
    add_model_file(
        rep,
        "the model (friction and effects), e.g. from rc1 diagnose (default: the paper's identified friction)",
        metavar="MODEL.yaml",
    )
    rep.add_argument("--friction", type=friction_override, action="append", default=[], metavar="NAME=VALUE")
    rep.add_argument(
        "--effect",
        type=effect_arg,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect to the model (see rc1 effects); repeatable",
    )
    rep.add_argument(
        "--servo",
        type=servo_override,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"set a working servo's gain ({', '.join(SERVO_NAMES)}; default the model's); repeatable",
    )
    rep.add_argument(
        "--joints",
        type=joint_list_arg,
        default=list(range(1, 14)),
        metavar="LIST",
        help="failed joints, e.g. 2,7 (default 1-13); no failure always runs, J7+bias with 7",
    )
    rep.add_argument(
        "--trials",
        type=positive_int,
        default=PAPER_TRIALS,
        metavar="N",
        help=f"trials per case (default {PAPER_TRIALS}, as the paper)",
    )
    rep.add_argument(
        "--time-limit-s",
        type=float_arg,
        default=TIME_LIMIT_S,
        metavar="T",
        help=f"end a run that neither reached the line nor circled twice after T s (default {TIME_LIMIT_S:g}: "
        "long enough for a circle up to about 3.5 m across)",
    )
    rep.add_argument("--json", type=Path, metavar="PATH", help="write every case, trial and finding")
    rep.add_argument("--plots", type=Path, metavar="DIR", help="write figures in the style of the paper's Figs. 8-13")
    rep.add_argument("--workers", type=positive_int, metavar="N", help="local processes (default: every core)")
    rep.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")


def cmd_reproduce(args) -> int:
    import matplotlib.pyplot as plt

    from ..reproduce import reproduce

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
        write_atomically(args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2) + "\n"))
    if args.plots:
        figures = {"findings.png": result.figure(), "cases.png": result.figure(cases=tuple(result.cases))}
        for name, fig in figures.items():
            write_atomically(args.plots / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
            plt.close(fig)
    return 0
