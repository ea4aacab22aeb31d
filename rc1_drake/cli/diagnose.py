"""`rc1 diagnose`: the missing-physics loop, its report, page and discovery."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

from ..config import (
    FRICTION_NAMES,
    Friction,
    Rc1Error,
)
from ..diagnose import INPUT_NOISE_SAMPLES as DIAGNOSE_NOISE_SAMPLES
from ..diagnose import THRESHOLDS
from ..scenarios import ModelFile, load_model_file, model_to_yaml
from ..sysid.evaluate import Checkpoint
from .compare import write_compare_plots
from .options import (
    add_checkpoint,
    add_model_file,
    add_outputs,
    add_start_rates,
    candidates_arg,
    jsonable,
    loaded_campaign,
    non_negative,
    positive_int,
    write_atomically,
)


def add_diagnose(sub) -> None:
    dgn = sub.add_parser(
        "diagnose",
        help="find the missing physics: fit, where it fails, rank candidate effects, "
        "accept what holds on held-out trials, repeat",
    )
    dgn.add_argument("campaign", type=Path, nargs="+", help="a campaign folder, or several diagnosed as one (a "
                     "campaign and the trials of its plan: rc1 design, rc1 synthesize --plan)")  # fmt: skip
    add_model_file(
        dgn,
        "today's model (friction and effects; default: the paper's identified friction, no effect)",
        metavar="MODEL.yaml",
    )
    dgn.add_argument(
        "--candidates",
        type=candidates_arg,
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
    dgn.add_argument("--rounds", type=positive_int, default=3, metavar="N", help="effects to add at most (default 3)")
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
        type=positive_int,
        default=DIAGNOSE_NOISE_SAMPLES,
        metavar="K",
        help="noisy replays of each trial's noise-free twin, for the replay's own miss and its input "
        f"noise (default {DIAGNOSE_NOISE_SAMPLES})",
    )
    dgn.add_argument(
        "--failed-joint-scatter",
        type=non_negative,
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
    add_start_rates(
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
    add_checkpoint(dgn, default="<campaign>")
    add_outputs(
        dgn, out_help="write the diagnosed model (friction and accepted effects; default out/<campaign>.model.yaml)"
    )


def cmd_diagnose(args) -> int:
    import matplotlib.pyplot as plt

    from ..diagnose import diagnose
    from ..plots import candidates_figure, waterfall_figure

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
        write_atomically(out, lambda p: p.write_text(model_to_yaml(friction, effects, comment=note)))
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
    write_atomically(out, lambda p: p.write_text(model_to_yaml(result.friction, result.effects, comment=note)))
    resumed = f", {result.resumed} of them from an interrupted run's checkpoint" if result.resumed else ""
    print(f"model file: {out}  ({result.simulations} simulations{resumed}, {result.wall_s:.0f} s)")
    if args.json:
        write_atomically(
            args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2, default=jsonable) + "\n")
        )
    if args.report:
        from ..diagnose.page import report_page

        page = report_page(result, campaign, model_yaml=out.read_text(), command=args.command_line)
        write_atomically(args.report / "index.html", lambda p: p.write_text(page))
        print(f"report: {args.report / 'index.html'}")
    if args.plots:
        write_compare_plots(result.report, campaign, args.plots / "where_it_fails")
        for name, fig in {
            "waterfall.png": waterfall_figure(result.waterfall),
            "candidates.png": candidates_figure(result.candidates),
        }.items():
            write_atomically(args.plots / name, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
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
    from ..diagnose.discover import discover_campaign

    found = discover_campaign(
        result.trials, result.friction, result.effects, workers=args.workers, scheduler=args.scheduler,
        progress=progress, angles=args.angles,
    )  # fmt: skip
    print(found.format())
    if found.terms:
        note += f"; discovered {', '.join(t.key for t in found.terms)}"
        write_atomically(out, lambda p: p.write_text(model_to_yaml(result.friction, found.effects, comment=note)))
        print(f"model file with the discovered terms: {out}")
