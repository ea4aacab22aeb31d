"""The paper's section-4 findings against a model, and what `rc1 reproduce` costs: written into docs/paper.md.

    python benchmarks/paper.py [--model-file MODEL.yaml] [--servo KEY=VALUE ...] [--workers N] [--markdown]

Runs `rc1 reproduce`'s library call (reproduce.reproduce: no failure, joints 1-13 failed in turn, J7+bias, five
trials each, the compiled engine) once to compile the kernels on a single case, then the whole of it timed, and
prints the findings table, the runs and the wall time beside one 10 s run's (so that another machine compares).
--markdown writes the table and the timing into docs/paper.md (its paper-table markers) and the figure of the
paper's Figs. 8 and 10-13 to docs/paper_findings.png.
"""

import argparse
import dataclasses
import os
import time

from doc_blocks import REPO_ROOT, check_block, write_block

from rc1_drake.cli import _servo_override
from rc1_drake.config import Scenario, Servo, Stop
from rc1_drake.engine import make_session
from rc1_drake.reproduce import reproduce
from rc1_drake.scenarios import load_model_file

PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "paper.md", "paper-table", "benchmarks/paper.py --markdown"


def single_run_s() -> float:
    """Wall time of one 10 s nominal run on the compiled engine (kernels compiled): the machine's unit."""
    scenario = Scenario(stop=Stop(line_x_m=None, revolutions=None, time_limit_s=10.0))
    session = make_session(scenario, engine="compiled")
    session.simulate(scenario)
    return session.simulate(scenario).wall_time_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model-file", help="a model file (friction and effects; default: the paper's model)")
    parser.add_argument("--servo", type=_servo_override, action="append", default=[], metavar="KEY=VALUE",
                        help="a working servo's gain (a config.Servo field); repeatable")  # fmt: skip
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--markdown", action="store_true", help="write the table and figure into docs/")
    args = parser.parse_args()
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
    model = load_model_file(args.model_file) if args.model_file else None
    kwargs = {"friction": model.friction, "effects": model.effects} if model else {}
    kwargs["servo"] = dataclasses.replace(Servo(), **dict(args.servo))
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
    model_text = f"the model of `{args.model_file}`" if args.model_file else "the paper's model"
    model_text += "".join(f", servo {k}={v:g}" for k, v in args.servo)
    print(result.format())
    print(timing)
    if args.markdown:
        body = (
            f"Measured by `python benchmarks/paper.py --markdown` (last run {time.strftime('%Y-%m-%d')}; "
            f"{model_text}; {timing}):\n\n```\n{result.format()}\n```"
        )
        write_block(PAGE, BLOCK, WRITER, body)
        figure = result.figure()
        figure.savefig(REPO_ROOT / "docs" / "paper_findings.png", dpi=110)


if __name__ == "__main__":
    main()
