"""`rc1 synthesize`: a campaign in the measurement format from a truth model."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from ..config import (
    TRUTH_MODELS,
    Rc1Error,
    Scenario,
    Stop,
)
from ..scenarios import validate
from .options import effect_arg, float_arg, friction_override, positive_int, validate_friction


def add_synthesize(sub) -> None:
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
        type=positive_int,
        metavar="N",
        help="trials in each case (the paper design's lone joint-2 trial stays one)",
    )
    syn.add_argument("--time-limit-s", type=float_arg, metavar="T", help="end every trial after T s at the latest")
    syn.add_argument(
        "--friction",
        type=friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="the truth's friction coefficient (repeatable; default: the paper's identified set)",
    )
    syn.add_argument(
        "--effect",
        type=effect_arg,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a physical effect in the truth (EFFECT=VALUE or PARAMETER=VALUE, see rc1 effects); repeatable",
    )
    syn.add_argument(
        "--form",
        type=form_arg,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="another form of robot or lab, read by the reference truth model only: reference_stop_Nm_per_rad, "
        "reference_stop_Nm_s_per_rad (its failed joints' stop), reference_linkage_rad_per_Nm, "
        "reference_potentiometer_step_deg, reference_camera_marker_m, reference_camera_scale_error (its sensors: "
        "synthesize.LabForms), floor_seam_Nm, floor_seam_x_m; repeatable",
    )
    syn.add_argument("--noise-scale", type=float_arg, default=1.0, metavar="S", help="multiply every sensor noise by S")
    syn.add_argument("--no-camera", action="store_true", help="leave out the overhead camera columns")
    syn.add_argument(
        "--truth-model",
        choices=TRUTH_MODELS,
        default="drake",
        help="drake: this project's Diagram through its servos; reference: the independent planar model "
        "of reference.py (kinematic joints, its own limit model, the head at rest at its start; effects: "
        "wheel_toe, tail_tether, servo_linkage, the sensor faults and the discrepancy terms; and --form)",
    )
    syn.add_argument("--sample-period-s", type=float_arg, default=0.01, metavar="DT", help="the sensors' sample period")
    syn.add_argument(
        "--record-after-s",
        type=float_arg,
        default=0.0,
        metavar="T",
        help="start the recording T s after the robot started (the data then begin in motion)",
    )
    syn.add_argument("--plan", type=Path, metavar="PLAN", help="the trials of a plan (rc1 design --out), in place "
                     "of --design, at its lab's sample period and potentiometer noise")  # fmt: skip
    syn.add_argument("--seed", type=int, default=0)
    syn.add_argument("--truth", type=Path, metavar="PATH", help="where to record the truth (JSON)")


def form_arg(text: str) -> tuple[str, float]:
    from ..synthesize import REFERENCE_ONLY

    key, sep, value = text.partition("=")
    if key not in REFERENCE_ONLY:
        raise argparse.ArgumentTypeError(f"unknown form {key!r} (known: {', '.join(REFERENCE_ONLY)})")
    try:
        return key, float(value if sep else "")
    except ValueError:
        raise argparse.ArgumentTypeError(f"form {key!r} needs a number: {key}=VALUE") from None


def cmd_synthesize(args) -> int:
    from ..synthesize import DESIGNS, Noise, synthesize_campaign

    if args.out.exists():
        raise Rc1Error(f"{args.out}: already exists; synthesize writes a new campaign folder")
    design, sample_period_s, noise = DESIGNS[args.design], args.sample_period_s, Noise().scaled(args.noise_scale)
    if args.plan:
        from ..design import load_plan

        if args.trials_per_case:
            raise Rc1Error("--trials-per-case sets --design's cases; a plan's trials are one each")
        designs, lab = load_plan(args.plan)
        design, sample_period_s = [d.case() for d in designs], lab.sample_period_s
        noise = dataclasses.replace(noise, potentiometer_deg=lab.potentiometer_deg * args.noise_scale)
    elif args.trials_per_case:
        design = [
            dataclasses.replace(c, trials=args.trials_per_case if c.trials > 1 or args.design != "paper" else c.trials)
            for c in design
        ]
    stop = None if args.time_limit_s is None else Stop(time_limit_s=args.time_limit_s)
    friction = validate_friction(dict(args.friction))
    effects = dict(args.effect)
    validate(Scenario(effects=effects, stop=stop or Stop()), where="command line")
    effects |= dict(args.form)  # synthesize_campaign refuses them for the drake truth, and checks their values
    campaign = synthesize_campaign(
        args.out,
        design=design,
        friction=friction,
        effects=effects,
        noise=noise,
        camera=not args.no_camera,
        seed=args.seed,
        truth_file=args.truth,
        stop=stop,
        truth_model=args.truth_model,
        sample_period_s=sample_period_s,
        record_after_s=args.record_after_s,
    )
    print(f"wrote {len(campaign.trials)} trials to {args.out}" + (f"; truth in {args.truth}" if args.truth else ""))
    return 0
