"""`rc1 identify`: the five friction coefficients by AVS, the program fit or equation error."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..config import (
    FRICTION_NAMES,
)
from ..identify import INPUT_NOISE_SAMPLES
from ..scenarios import load_model_file
from ..sysid.evaluate import Checkpoint
from .options import (
    NAMED_MODEL,
    add_checkpoint,
    add_outputs,
    add_start_rates,
    count_arg,
    loaded_campaign,
    positive_int,
    write_atomically,
)


def add_identify(sub) -> None:
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
        type=positive_int,
        default=10,
        metavar="N",
        help="AVS iterations, or the program fit's at most (default 10)",
    )
    idn.add_argument(
        "--input-noise-samples",
        type=count_arg,
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
    add_start_rates(
        idn,
        default="rest",
        fit="fitted once per trial to its first 0.5 s of camera path and IMU, "
        "at the start model, and held through the fit",
    )
    add_checkpoint(idn, default="<campaign>-identify")
    add_outputs(idn, out_help="write a model file: the identified coefficients and the (fixed) effects")


def cmd_identify(args) -> int:
    import matplotlib.pyplot as plt

    from ..identify import avs_figure, friction_to_yaml, identify

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
        write_atomically(fit_model, lambda p: p.write_text(friction_to_yaml(fit.friction, start and start.effects)))
        record = {"stage": "fit (its uncertainty and held-out errors not computed yet)", **fit.to_json()}
        write_atomically(fit_json, lambda p: p.write_text(json.dumps(record, indent=2, default=float) + "\n"))
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
        write_atomically(
            args.json, lambda p: p.write_text(json.dumps(result.to_json(), indent=2, default=float) + "\n")
        )
    if args.out:
        write_atomically(args.out, lambda p: p.write_text(friction_to_yaml(result.friction, result.effects)))
    if args.plots and args.method == "avs":
        fig = avs_figure(result.result)
        write_atomically(args.plots / "avs_iterations.png", lambda p: fig.savefig(p, format="png", dpi=110))
        plt.close(fig)
    for path in {fit_model, fit_json} - {args.out, args.json}:  # kept for a failure; the report has them now
        path.unlink(missing_ok=True)
    Checkpoint.discard(checkpoint)
    return 0
