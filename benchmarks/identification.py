"""Friction identification: which campaign designs identify which coefficients, and what each method
costs in simulations to get there.

    python benchmarks/identification.py [--time-limit-s 3] [--seed 8] [--workers 2] [--avs-iterations 10]
                                        [--only design|recovery|cost] [--markdown]

1. design: for each design (the paper's cases; + gaits at 70 and 210 deg/s; + failures at two speeds =
   synthesize.IDENTIFICATION_DESIGN; + a joint-2 failure) it synthesizes a campaign (the paper's
   friction, default noise) and prints each coefficient's relative standard error at the truth
   (identify.uncertainty: 1 + 5 residual evaluations), whether it is identifiable (< 30%), and the
   worst trial's RMS standardized residual at the truth: ~0.6 is sensor noise, more means the replay
   cannot reproduce that trial even at the true coefficients, and it will bias a fit.
2. recovery: the program fit from the paper's manual values with all five free on the identification
   design, screened (identify.screen: coefficients not identifiable at the start are held there, not
   fitted), and unscreened: value, error against the truth, standard error, simulations, wall time.
3. cost: AVS from the manual values on the same campaign: its Eq. 6 error and simulations, and the
   simulations the program fit needed to reach that error (its Eq. 6 error is scored after each
   iteration, outside the count).

--markdown writes the design study's table into docs/identification.md (its identification-design markers).
"""

import argparse
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
from doc_blocks import REPO_ROOT, check_block, write_block

from rc1_drake.config import FRICTION_NAMES, Friction, Gait, Stop
from rc1_drake.executor import make_executor
from rc1_drake.identify import Eq6Objective, avs, fit_program, screen
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import IDENTIFICATION_DESIGN, Case, synthesize_campaign
from rc1_drake.sysid.input_noise import INPUT_NOISE_SAMPLES
from rc1_drake.sysid.objective import CampaignResiduals
from rc1_drake.sysid.parameters import PAPER_MANUAL
from rc1_drake.sysid.residual import replay_residual
from rc1_drake.sysid.stats import uncertainty

DESIGNS = {
    "no failure + joint 7, 140 deg/s": [Case([], 1), Case([7], 1)],
    "+ no failure at 70 and 210 deg/s": [
        Case([], 1),
        Case([7], 1),
        Case([], 1, gait=Gait(frequency_deg_s=70.0)),
        Case([], 1, gait=Gait(frequency_deg_s=210.0)),
    ],
    "+ joint 7 at 210, joint 13 (IDENTIFICATION)": IDENTIFICATION_DESIGN,
    "+ joint 2 (circling)": IDENTIFICATION_DESIGN + [Case([2], 1)],
}


def campaign(folder, design, args):
    synthesize_campaign(
        folder,
        design=design,
        seed=args.seed,
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=args.time_limit_s),
    )
    return load_campaign(folder)


PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "identification.md", "identification-design", "benchmarks/identification.py"


def design_study(args, executor, workdir) -> list:
    """Per design: (name, relative standard errors %, identifiable flags, worst replay RMS, trial-seconds for 10%)."""
    rows = []
    print(
        f"\n1. relative standard error at the truth, % ({args.time_limit_s:g} s trials, seed {args.seed}, "
        f"input noise from {args.input_noise_samples} resampled replays per trial); * = identifiable (< 30%)"
    )
    print(
        f"{'design':45}" + "".join(f"{n:>10}" for n in FRICTION_NAMES) + f"{'replay rms':>11}{'sims':>6}{'wall s':>8}"
    )
    for k, (name, design) in enumerate(DESIGNS.items()):
        start = time.perf_counter()
        trials = campaign(workdir / f"design{k}", design, args).trials
        spread = uncertainty(
            CampaignResiduals(trials, executor=executor), Friction(), input_noise_samples=args.input_noise_samples
        )
        cells = "".join(
            f"{(100 * se / v if se != float('inf') else float('inf')):>9.0f}{'*' if ok else ' '}"
            for v, se, ok in zip(spread.values, spread.standard_errors, spread.identifiable, strict=True)
        )
        worst = max(float(np.sqrt(np.mean(replay_residual(t, Friction()) ** 2))) for t in trials)
        print(f"{name:45}{cells}{worst:>11.2f}{spread.simulations:>6}{time.perf_counter() - start:>8.0f}", flush=True)
        # Standard errors fall as 1/sqrt(data): trial-seconds of this design that a 10% error would need.
        seconds = len(trials) * args.time_limit_s
        need = "".join(
            f"{seconds * (100 * se / v / 10) ** 2 if se != float('inf') else float('inf'):>10.3g}"
            for v, se in zip(spread.values, spread.standard_errors, strict=True)
        )
        print(f"{'  trial-seconds for a 10% standard error':45}{need}", flush=True)
        relative = [
            100 * se / v if se != float("inf") else float("inf")
            for v, se in zip(spread.values, spread.standard_errors, strict=True)
        ]
        rows.append((name, relative, list(spread.identifiable), worst, [seconds * (r / 10) ** 2 for r in relative]))
    return rows


def design_table(rows, args) -> str:
    lines = [
        f"Measured by `python {WRITER} --only design --markdown` (last run {time.strftime('%Y-%m-%d')}; "
        f"{args.time_limit_s:g} s trials, the paper's friction as truth, default sensor noise, seed {args.seed}; the "
        f"uncertainty at the truth with {args.input_noise_samples} resampled replays per trial). Relative standard "
        "error, % (bold: identifiable, under 30%), the worst trial's RMS standardized residual at the truth (0.6 is "
        "sensor noise; more, the replay cannot reproduce that trial even at the true coefficients), and the "
        "trial-seconds of each design that a 10% error would need:",
        "",
        "| design (one trial per case) | " + " | ".join(FRICTION_NAMES) + " | worst replay RMS |",
        "|---|" + "---|" * (len(FRICTION_NAMES) + 1),
    ]
    for name, relative, ok, worst, need in rows:
        cells = [f"**{r:.0f}**" if good else f"{r:.0f}" for r, good in zip(relative, ok, strict=True)]
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {worst:.2f} |")
        lines.append("| (trial-seconds for 10%) | " + " | ".join(f"{n:,.0f}" for n in need) + " | |")
    return "\n".join(lines)


def recovery_and_cost(args, executor, workdir, only):
    trials = campaign(workdir / "identification", IDENTIFICATION_DESIGN, args).trials
    truth = Friction()
    scores = {}
    eq6 = Eq6Objective(trials, executor=executor)  # scoring only: not counted against the fits
    if only in (None, "recovery", "cost"):
        for screened in (True, False):
            residuals = CampaignResiduals(trials, executor=executor)
            start = time.perf_counter()
            history = []
            fitted = screen(residuals, PAPER_MANUAL)[0] if screened else None
            fit = fit_program(
                residuals,
                start=PAPER_MANUAL,
                parameters=fitted,
                max_iterations=args.program_iterations,
                on_iteration=lambda f, sims, h=history: h.append((sims, eq6(f))),
            )
            wall = time.perf_counter() - start
            spread = uncertainty(residuals, fit.friction)
            held = [p.name for p in fitted if p.frozen] if screened else []
            print(
                f"\n2. program fit from the manual values, {'screened' if screened else 'all five fitted'}, "
                f"{len(trials)} trials ({fit.iterations} iterations, {residuals.simulations} trial simulations "
                f"with the screening, {wall:.0f} s wall)"
            )
            print(f"{'coefficient':12}{'truth':>8}{'result':>9}{'error %':>9}{'std err %':>11}  fitted")
            for name, value, se, ok in zip(
                spread.names, spread.values, spread.standard_errors, spread.identifiable, strict=True
            ):
                t = getattr(truth, name)
                print(
                    f"{name:12}{t:>8.4g}{value:>9.4g}{100 * (value - t) / t:>9.1f}{100 * se / value:>11.1f}  "
                    f"{'held at start' if name in held else 'yes'}{'' if ok else ' (not identifiable at the result)'}"
                )
            scores["screened" if screened else "program"] = history
            print(
                "mean Eq. 6 error after each iteration (trial simulations so far): "
                + ", ".join(f"{e:.2f}% ({s})" for s, e in history)
            )
    if only in (None, "cost"):
        start = time.perf_counter()
        objective = Eq6Objective(trials, executor=executor)
        result = avs(objective, start=PAPER_MANUAL, iterations=args.avs_iterations)
        wall = time.perf_counter() - start
        print(
            f"\n3. AVS from the manual values, {args.avs_iterations} iterations: Eq. 6 error "
            f"{result.start_error:.2f}% -> {result.error:.2f}%, {result.simulations} trial simulations, {wall:.0f} s"
        )
        print(result.table())
        for name, history in scores.items():
            reached = next((s for s, e in history if e <= result.error), None)
            print(
                f"{name} fit reached AVS's error after "
                f"{'(never, within its iterations)' if reached is None else f'{reached} trial simulations'}"
            )
        print(f"the truth's own mean Eq. 6 error on these trials: {eq6(truth):.2f}%")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-limit-s", type=float, default=3.0)
    parser.add_argument("--seed", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--avs-iterations", type=int, default=10)
    parser.add_argument("--program-iterations", type=int, default=10)
    parser.add_argument("--only", choices=["design", "recovery", "cost"])
    parser.add_argument(
        "--input-noise-samples",
        type=int,
        default=INPUT_NOISE_SAMPLES,
        help="resampled replays per trial for the input-noise part of the intervals (0: leave it out)",
    )
    parser.add_argument("--markdown", action="store_true", help="write the design table into docs/identification.md")
    args = parser.parse_args()
    if args.markdown:
        if args.only != "design":
            parser.error("--markdown writes the design study's table: run it with --only design")
        check_block(PAGE, BLOCK, WRITER)
    print(
        f"machine: {platform.processor() or platform.machine()}, {args.workers} workers, "
        f"python {platform.python_version()}"
    )
    with tempfile.TemporaryDirectory() as tmp, make_executor(workers=args.workers) as executor:
        workdir = Path(tmp)
        if args.only in (None, "design"):
            rows = design_study(args, executor, workdir)
            if args.markdown:
                write_block(PAGE, BLOCK, WRITER, design_table(rows, args))
        if args.only != "design":
            recovery_and_cost(args, executor, workdir, args.only)


if __name__ == "__main__":
    main()
