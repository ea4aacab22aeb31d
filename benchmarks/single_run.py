"""Wall time of single runs (nominal and joint-7 failure) and their numerical convergence.

    python benchmarks/single_run.py [--repeats 3] [--no-reference] [--markdown]

Prints, per case: simulated time, wall time (best of the repeats, Diagram and Simulator reused),
the real-time factor, and how far the final head position moves (in % of the distance travelled)
when the time step or the sgn() smoothing is halved, or against the independent SciPy model
(rc1_drake.reference) driven by the joint angles the servos achieved. --markdown writes the table into
docs/model.md (its single-run markers).
"""

import argparse
import dataclasses
import platform
import time

import numpy as np
from doc_blocks import REPO_ROOT, check_block, write_block

from rc1_drake.config import Failure, Scenario
from rc1_drake.protocol import Session
from rc1_drake.reference import simulate_reference

CASES = {"nominal": [], "joint_7": [Failure(joint=7)]}
PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "model.md", "single-run", "benchmarks/single_run.py --markdown"


def moved(a_xy, b_xy, start):
    return 100 * np.linalg.norm(a_xy - b_xy) / np.linalg.norm(a_xy - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-reference", action="store_true", help="skip the (slow) SciPy reference")
    parser.add_argument("--markdown", action="store_true", help="write the table into docs/model.md")
    args = parser.parse_args()
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
    machine = f"{platform.processor() or platform.machine()}, python {platform.python_version()}"
    rows = []
    print(f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}")
    header = (
        f"{'case':10} {'sim s':>6} {'wall s':>7} {'x real':>7} {'dt/2 %':>7} {'eps/2 %':>8} {'ref %':>6} "
        f"{'ref wall s':>10}"
    )
    print(header)
    for name, failures in CASES.items():
        scenario = Scenario(failures=failures)
        session = Session(scenario)
        runs = [session.simulate(scenario) for _ in range(args.repeats)]
        run = min(runs, key=lambda r: r.wall_time_s)
        n = scenario.numerics
        finer = dataclasses.replace(scenario, numerics=dataclasses.replace(n, time_step_s=n.time_step_s / 2))
        sharper = dataclasses.replace(
            scenario, numerics=dataclasses.replace(n, sgn_smoothing_m_s=n.sgn_smoothing_m_s / 2)
        )
        fine = Session(finer).simulate(finer)
        sharp = session.simulate(sharper)
        start, end = run.head_xy[0], run.head_xy[-1]
        ref_pct, ref_wall = float("nan"), float("nan")
        if not args.no_reference:
            ref = simulate_reference(scenario, run.geometry, joint_path=(run.t, run.q), rtol=1e-5, atol=1e-7)
            ref_pct, ref_wall = moved(end, ref.head_xy[-1], start), ref.wall_time_s
        print(
            f"{name:10} {run.t[-1]:6.2f} {run.wall_time_s:7.2f} {run.t[-1] / run.wall_time_s:7.1f} "
            f"{moved(end, fine.head_xy[-1], start):7.2f} {moved(end, sharp.head_xy[-1], start):8.2f} "
            f"{ref_pct:6.2f} {ref_wall:10.1f}"
        )
        rows.append(
            f"| {name} | {run.t[-1]:.2f} s | {run.wall_time_s:.1f} s | {run.t[-1] / run.wall_time_s:.1f} | "
            f"{moved(end, fine.head_xy[-1], start):.2f}% | {moved(end, sharp.head_xy[-1], start):.2f}% | "
            f"{ref_pct:.2f}% | {ref_wall:.1f} s |"
        )
    if args.markdown:
        head = [
            f"Measured on {machine} by `python {WRITER}` (last run {time.strftime('%Y-%m-%d')}; the Drake Diagram, "
            f"best of {args.repeats}):",
            "",
            "| case | simulated | wall | real-time factor | dt/2 moves it | eps/2 moves it | vs reference "
            "| reference wall |",
            "|---|---|---|---|---|---|---|---|",
        ]
        write_block(PAGE, BLOCK, WRITER, "\n".join(head + rows))


if __name__ == "__main__":
    main()
