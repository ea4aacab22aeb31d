"""`rc1 compare`: replay a campaign against the model: Eq. 6, Table 2, where it fails."""

from __future__ import annotations

import json
from pathlib import Path

from ..config import (
    Scenario,
)
from ..progress import Counter
from ..scenarios import validate
from .options import (
    add_model_file,
    add_start_rates,
    effect_arg,
    friction_override,
    loaded_campaign,
    model_from_args,
    positive_int,
    write_atomically,
)


def add_compare(sub) -> None:
    cmp = sub.add_parser("compare", help="replay a campaign through the model and score it (Eq. 6, Table 2)")
    cmp.add_argument("campaign", type=Path, help="campaign folder (data/README.md)")
    cmp.add_argument(
        "--friction",
        type=friction_override,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="friction coefficient for the model (repeatable)",
    )
    add_model_file(
        cmp,
        "a model file (friction and effects), e.g. from rc1 identify --out or rc1 diagnose",
        aliases=("--friction-file",),
    )
    cmp.add_argument(
        "--effect",
        type=effect_arg,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="add a physical effect to the model (see rc1 effects); repeatable",
    )
    cmp.add_argument("--json", type=Path, metavar="PATH", help="write every per-trial and per-case number")
    cmp.add_argument("--plots", type=Path, metavar="DIR", help="write figures in the paper's styles")
    add_start_rates(cmp, default="rest", fit="to its first 0.5 s of camera path and IMU")
    cmp.add_argument("--workers", type=positive_int, metavar="N", help="processes (default: every core)")


def cmd_compare(args) -> int:
    from ..compare import compare_campaign

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
    from ..residuals import where_it_fails

    where = where_it_fails(report, campaign)
    print()
    print(
        "Where the model fails (worst first; path error from the camera; LB p: whiteness of the yaw-rate "
        "residual, small = structure left; the feature it correlates with most):"
    )
    print(where.table())
    if args.json:
        record = {**report.to_json(), "where_it_fails": where.to_json()}
        write_atomically(args.json, lambda p: p.write_text(json.dumps(record, indent=2) + "\n"))
    if args.plots:
        write_compare_plots(report, campaign, args.plots)
    return 0


def write_compare_plots(report, campaign, folder: Path) -> None:
    import matplotlib.pyplot as plt

    from ..plots import compare_figures

    for case_figures in compare_figures(report, campaign).values():
        for filename, fig in case_figures.items():
            write_atomically(folder / filename, lambda p, fig=fig: fig.savefig(p, format="png", dpi=110))
            plt.close(fig)
