"""Fit a mechanism's parameters to the paper's section-4 figures by its own AVS (rc1_drake.paper_fit), then score
the best point on every finding (rc1 reproduce, five trials).

    python benchmarks/paper_fit.py --fit ki_Nm_per_rad_s=0:5:0 --fit kp_Nm_per_rad=1:20:5 [--iterations 8]
        [--trials 2] [--workers N] [--json PATH]

--fit NAME=LOWER:UPPER:START: a friction coefficient, a working servo's gain (kp_Nm_per_rad, ki_Nm_per_rad_s,
kd_Nm_s_per_rad, torque_limit_Nm) or an effect parameter (rc1 effects); the others stay the model's.
"""

import argparse
import dataclasses
import json
import time

from rc1_drake.paper_fit import fit_table, fit_to_paper, mechanism_parameter, model_of
from rc1_drake.reproduce import reproduce


def parse_fit(text: str) -> tuple:
    name, _, bounds = text.partition("=")
    try:
        lower, upper, start = (float(v) for v in bounds.split(":"))
        return mechanism_parameter(name, lower, upper), start
    except ValueError as e:
        problem = e if "parameter" in str(e) else "expected NAME=LOWER:UPPER:START"
        raise argparse.ArgumentTypeError(f"--fit {text}: {problem}") from None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fit", type=parse_fit, action="append", required=True, metavar="NAME=LO:HI:START")
    parser.add_argument("--iterations", type=int, default=8)
    parser.add_argument("--trials", type=int, default=2, help="trials per case in the fit (5 in the final score)")
    parser.add_argument("--workers", type=int)
    parser.add_argument("--json", help="write the fit's history and the final findings")
    args = parser.parse_args()
    parameters, starts = zip(*args.fit, strict=True)
    started = time.perf_counter()

    def progress(done, total, name, cost):
        print(
            f"  iteration {done}/{total}: {name}, cost {cost:.3f} ({time.perf_counter() - started:.0f} s)", flush=True
        )

    result, objective = fit_to_paper(
        list(parameters),
        {p.name: s for p, s in zip(parameters, starts, strict=True)},
        iterations=args.iterations,
        trials=args.trials,
        workers=args.workers,
        progress=progress,
    )
    print(fit_table(objective))
    best = dataclasses.asdict(result.friction)
    friction, effects, servo = model_of(best)
    final = reproduce(friction=friction, effects=effects, servo=servo, workers=args.workers)
    print(f"best {best} (cost {result.error:.3f}; {objective.simulations} runs in the fit, "
          f"{time.perf_counter() - started:.0f} s)")  # fmt: skip
    print(final.format())
    if args.json:
        record = {"best": best, "cost": result.error, "history": objective.history, "findings": final.to_json()}
        with open(args.json, "w") as f:
            json.dump(record, f, indent=2, default=float)


if __name__ == "__main__":
    main()
