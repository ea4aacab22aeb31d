"""The paper's section-4 findings against a model, and what `rc1 reproduce` costs: written into docs/paper.md.

    python benchmarks/paper.py [--scenarios-file FILE [--scenario NAME]] [--workers N] [--markdown]

Runs `rc1 reproduce`'s library call (reproduce.reproduce: no failure, joints 1-13 failed in turn, J7+bias, five
trials each, the compiled engine) once to compile the kernels on a single case, then the whole of it timed, and
prints the findings table, the runs and the wall time beside one 10 s run's (so that another machine compares).
--markdown writes the table and the timing into docs/paper.md (its paper-table markers; with --scenarios-file
FILE, its paper-table-<FILE's stem> markers) and the figure of the paper's Figs. 8 and 10-13 to
docs/paper_findings.png (paper_findings_<stem>.png). --scenarios-file takes the model (friction, effects and the
working servos' gains) from a scenario of a scenario file (scenarios/paper_findings.yaml).
"""

import argparse
import os
import time
from pathlib import Path

from doc_blocks import REPO_ROOT, check_block, write_block

from rc1_drake.config import Scenario, Stop
from rc1_drake.engine import make_session
from rc1_drake.reproduce import reproduce
from rc1_drake.scenarios import load_scenario

PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "paper.md", "paper-table", "benchmarks/paper.py --markdown"


def single_run_s() -> float:
    """Wall time of one 10 s nominal run on the compiled engine (kernels compiled): the machine's unit."""
    scenario = Scenario(stop=Stop(line_x_m=None, revolutions=None, time_limit_s=10.0))
    session = make_session(scenario, engine="compiled")
    session.simulate(scenario)
    return session.simulate(scenario).wall_time_s


def model_of_args(args) -> tuple:
    """(reproduce's model keywords, its words in the docs, the docs block and figure it writes)."""
    if args.scenarios_file:
        scenario = load_scenario(args.scenario, filename=args.scenarios_file)
        kwargs = {"friction": scenario.friction, "effects": scenario.effects, "servo": scenario.servo}
        stem = Path(args.scenarios_file).stem
        text = f"the model of `{args.scenarios_file}` (its scenario `{args.scenario}`)"
        return kwargs, text, f"{BLOCK}-{stem}", f"paper_findings_{stem}.png"
    return {}, "the paper's model", BLOCK, "paper_findings.png"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios-file", help="score the model of a scenario file (friction, effects, servos)")
    parser.add_argument("--scenario", default="nominal", help="the scenario of --scenarios-file (default nominal)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--markdown", action="store_true", help="write the table and figure into docs/")
    args = parser.parse_args()
    kwargs, model_text, block, figure_name = model_of_args(args)
    if args.markdown:
        check_block(PAGE, block, WRITER)
    reproduce(joints=[2], trials=1, workers=1, **kwargs)  # compiles the kernels, outside the timing
    unit = single_run_s()
    started = time.perf_counter()
    result = reproduce(workers=args.workers, **kwargs)
    wall = time.perf_counter() - started
    runs = sum(len(c.trials) for c in result.cases.values())
    timing = (
        f"{runs} runs in {wall:.0f} s on {args.workers} worker(s), the kernels compiled; one 10 s run takes "
        f"{unit:.2f} s on this machine (so the whole is {wall / unit:.0f} such runs)"
    )
    print(result.format())
    print(timing)
    if args.markdown:
        command = "python benchmarks/paper.py" + (
            f" --scenarios-file {args.scenarios_file} --scenario {args.scenario}" if args.scenarios_file else ""
        )
        body = (
            f"Measured by `{command} --markdown` (last run {time.strftime('%Y-%m-%d')}; "
            f"{model_text}; {timing}):\n\n```\n{result.format()}\n```"
        )
        write_block(PAGE, block, WRITER, body)
        result.figure().savefig(REPO_ROOT / "docs" / figure_name, dpi=110)


if __name__ == "__main__":
    main()
