"""Friction identification: which campaign designs identify which coefficients, and what each method
costs in simulations to get there.

    python benchmarks/identification.py [--time-limit-s 3] [--seed 8] [--workers 2] [--avs-iterations 10]
                                        [--only design|recovery|cost]

1. design: for each design (the paper's cases; + other gait speeds and a standing wave; + failures in
   the standing wave; + a fast gait = synthesize.IDENTIFICATION_DESIGN) it synthesizes a campaign (the
   paper's friction, default noise) and prints each coefficient's relative standard error at the truth
   (identify.uncertainty: 1 + 5 residual evaluations) and whether it is identifiable (< 30%).
2. recovery: the program fit from the paper's manual values with all five free on the identification
   design: value, error against the truth, standard error, simulations, wall time.
3. cost: AVS from the manual values on the same campaign: its Eq. 6 error and simulations, and the
   simulations the program fit needed to reach that error (its Eq. 6 error is scored after each
   iteration, outside the count).
"""

import argparse
import dataclasses
import platform
import tempfile
import time
from pathlib import Path

from rc1_drake.config import FRICTION_NAMES, Friction, Gait, Stop
from rc1_drake.executor import make_executor
from rc1_drake.identify import PAPER_MANUAL, CampaignResiduals, Eq6Objective, avs, fit_program, uncertainty
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import IDENTIFICATION_DESIGN, PAPER_DESIGN, STANDING_WAVE, Case, synthesize_campaign

DESIGNS = {
    "paper cases (1 trial each)": [dataclasses.replace(c, trials=1) for c in PAPER_DESIGN[:2]],
    "+ 70 deg/s, standing wave": [Case([], 1), Case([7], 1), Case([], 1, gait=Gait(frequency_deg_s=70.0)),
                                  Case([], 1, gait=STANDING_WAVE)],
    "+ failures in the standing wave": [Case([], 1), Case([], 1, gait=Gait(frequency_deg_s=70.0)),
                                        Case([], 1, gait=Gait(amplitude_deg=30.0, frequency_deg_s=280.0)),
                                        Case([], 1, gait=STANDING_WAVE), Case([7], 1),
                                        Case([7], 1, gait=STANDING_WAVE), Case([2], 1, gait=STANDING_WAVE)],
    "+ 480 deg/s (IDENTIFICATION_DESIGN)": IDENTIFICATION_DESIGN,
}


def campaign(folder, design, args):
    synthesize_campaign(folder, design=design, seed=args.seed,
                        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=args.time_limit_s))
    return load_campaign(folder)


def design_study(args, executor, workdir):
    print(f"\n1. relative standard error at the truth, % ({args.time_limit_s:g} s trials, seed {args.seed}); "
          "* = identifiable (< 30%)")
    print(f"{'design':40}" + "".join(f"{n:>10}" for n in FRICTION_NAMES) + f"{'sims':>6}{'wall s':>8}")
    for k, (name, design) in enumerate(DESIGNS.items()):
        start = time.perf_counter()
        trials = campaign(workdir / f"design{k}", design, args).trials
        spread = uncertainty(CampaignResiduals(trials, executor=executor), Friction())
        cells = "".join(f"{(100 * se / v if se != float('inf') else float('inf')):>9.0f}{'*' if ok else ' '}"
                        for v, se, ok in zip(spread.values, spread.standard_errors, spread.identifiable, strict=True))
        print(f"{name:40}{cells}{spread.simulations:>6}"
              f"{time.perf_counter() - start:>8.0f}", flush=True)


def recovery_and_cost(args, executor, workdir, only):
    trials = campaign(workdir / "identification", IDENTIFICATION_DESIGN, args).trials
    truth = Friction()
    scores = {}
    eq6 = Eq6Objective(trials, executor=executor)  # scoring only: not counted against the fits
    if only in (None, "recovery", "cost"):
        residuals = CampaignResiduals(trials, executor=executor)
        start = time.perf_counter()
        history = []
        fit = fit_program(residuals, start=PAPER_MANUAL, max_iterations=args.program_iterations,
                          on_iteration=lambda f, sims: history.append((sims, eq6(f))))
        wall = time.perf_counter() - start
        spread = uncertainty(residuals, fit.friction)
        print(f"\n2. program fit from the manual values, all five free, {len(trials)} trials "
              f"({fit.iterations} iterations, {fit.simulations} trial simulations, {wall:.0f} s wall)")
        print(f"{'coefficient':12}{'truth':>8}{'fit':>9}{'error %':>9}{'std err %':>11}")
        for name, value, se in zip(spread.names, spread.values, spread.standard_errors, strict=True):
            t = getattr(truth, name)
            print(f"{name:12}{t:>8.4g}{value:>9.4g}{100 * (value - t) / t:>9.1f}{100 * se / value:>11.1f}")
        scores["program"] = history
        print("mean Eq. 6 error after each iteration (trial simulations so far): "
              + ", ".join(f"{e:.2f}% ({s})" for s, e in history))
    if only in (None, "cost"):
        start = time.perf_counter()
        objective = Eq6Objective(trials, executor=executor)
        result = avs(objective, start=PAPER_MANUAL, iterations=args.avs_iterations)
        wall = time.perf_counter() - start
        print(f"\n3. AVS from the manual values, {args.avs_iterations} iterations: Eq. 6 error "
              f"{result.start_error:.2f}% -> {result.error:.2f}%, {result.simulations} trial simulations, {wall:.0f} s")
        print(result.table())
        reached = next((s for s, e in scores.get("program", []) if e <= result.error), None)
        print(f"program fit reached AVS's error after "
              f"{'(never, within its iterations)' if reached is None else f'{reached} trial simulations'}; "
              f"truth's error {eq6(truth):.2f}%")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-limit-s", type=float, default=3.0)
    parser.add_argument("--seed", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--avs-iterations", type=int, default=10)
    parser.add_argument("--program-iterations", type=int, default=10)
    parser.add_argument("--only", choices=["design", "recovery", "cost"])
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {args.workers} workers, "
          f"python {platform.python_version()}")
    with tempfile.TemporaryDirectory() as tmp, make_executor(workers=args.workers) as executor:
        workdir = Path(tmp)
        if args.only in (None, "design"):
            design_study(args, executor, workdir)
        if args.only != "design":
            recovery_and_cost(args, executor, workdir, args.only)


if __name__ == "__main__":
    main()
