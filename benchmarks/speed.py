"""Speed: the project's targets measured in one table, both engines side by side (issues 8, 27).

    python benchmarks/speed.py [--only single,replay,batch,identification,diagnosis,plan,foreign] [--workers 2]
                               [--repeats 3] [--json benchmarks/out/speed.json] [--markdown]

1. single: the nominal run and the joint-7 failure (the default Scenario) on the Drake Diagram and on
   the compiled engine (best of --repeats, sessions reused): wall times, their ratio, the compiled
   engine's real-time factor, how far the two engines' final head positions are apart and how far the
   compiled run is from a converged one (time step / 4), in % of the distance travelled, and the
   project's independent SciPy model (reference.py) on the same case against the compiled engine.
2. replay: the shipped 10 s nominal trial replayed on each engine, a batch of 8 bootstrap replays
   (fresh angle noise each) on the compiled engine in one process, and the replay with its exact
   sensitivities to every friction coefficient and friction-law effect against the replay alone.
3. batch: the paper's sweep (no failure and joints 1-13, five trials each: 70 runs) through the
   executor with 1 and with --workers processes (process start included), on the compiled engine.
4. identification: on a synthesized identification campaign (3 s trials), AVS from the paper's manual
   values (10 iterations) against the program fit and the equation-error fit.
5. diagnosis: `rc1 diagnose` (every candidate effect) on the shipped 21-trial campaign.
6. plan: `rc1 design` from that diagnosis (budget 4, 8 drawn designs, one check replicate; issue 68 item 6).
7. foreign: `rc1 diagnose --start-rates fit` on 20 trials another model made (issue 67 item 6): reference.py, 5 each
   of no failure, J7, J13 and J7+bias, 10 s, 50 Hz, its failed joint's stop at 50 N m/rad; the campaign is made once
   (about 5 min, reference.py is serial) into benchmarks/out/speed_foreign and reused.

Each section prints as it finishes; the table at the end gives every figure with its target.
`--markdown` writes that table into docs/speed.md between its speed-table markers (a re-run section replaces its rows).
"""

import argparse
import dataclasses
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from doc_blocks import check_block, read_block, write_block
from single_run import moved  # benchmarks/ is on the path when this script runs

from rc1_drake.config import REPO_ROOT, Failure, Scenario, Stop
from rc1_drake.engine import use_engine
from rc1_drake.engine.session import CompiledSession
from rc1_drake.executor import make_executor
from rc1_drake.protocol import Session
from rc1_drake.reference import simulate_reference

SECTIONS = ("single", "replay", "batch", "identification", "diagnosis", "plan", "foreign")
TRIAL = REPO_ROOT / "data" / "paper_campaign" / "nominal_1.json"


def best(session, scenario, repeats):
    session.simulate(scenario)  # first run: numba's compiled kernels load
    return min((session.simulate(scenario) for _ in range(repeats)), key=lambda r: r.wall_time_s)


def single(args) -> list:
    rows = []
    for name, failures in {"nominal": [], "joint 7": [Failure(joint=7)]}.items():
        scenario = Scenario(failures=failures)
        drake = best(Session(scenario), scenario, args.repeats)
        run = best(CompiledSession(), scenario, args.repeats)
        n = scenario.numerics
        fine = dataclasses.replace(scenario, numerics=dataclasses.replace(n, time_step_s=n.time_step_s / 4))
        converged = CompiledSession().simulate(fine)
        error = float(moved(run.head_xy[-1], converged.head_xy[-1], run.head_xy[0]))
        apart = float(moved(run.head_xy[-1], drake.head_xy[-1], run.head_xy[0]))
        ref = simulate_reference(scenario, run.geometry, joint_path=(run.t, run.q), rtol=1e-5, atol=1e-7)
        speed = run.t[-1] / run.wall_time_s
        print(
            f"single {name}: {run.t[-1]:.2f} s simulated in {run.wall_time_s:.3f} s compiled ({speed:.0f}x real "
            f"time), {drake.wall_time_s:.2f} s Drake; engines {apart:.1e}% apart; {error:.2f}% from the run at "
            f"dt/4; SciPy reference {ref.wall_time_s:.1f} s",
            flush=True,
        )
        rows += [
            (f"{name} run, Drake wall (s)", drake.wall_time_s, "", None),
            (f"{name} run, compiled wall (s)", run.wall_time_s, "<= 0.1", run.wall_time_s <= 0.1),
            (f"{name} run, Drake / compiled", drake.wall_time_s / run.wall_time_s, "", None),
            (f"{name} run, compiled x real time", speed, ">= 100", speed >= 100),
            (
                f"{name} run, SciPy reference / compiled",
                ref.wall_time_s / run.wall_time_s,
                ">= 100",
                ref.wall_time_s / run.wall_time_s >= 100,
            ),
            (f"{name} run, engines apart (% of distance)", apart, "<= 0.2", apart <= 0.2),
            (f"{name} run, from converged (%)", error, "<= 1", error <= 1.0),
        ]
    return rows


def replay(args) -> list:
    from rc1_drake.config import FRICTION_NAMES
    from rc1_drake.effects import LIBRARY
    from rc1_drake.measurements import load_trial
    from rc1_drake.replay import Replayer, replay_scenario

    trial = load_trial(TRIAL)
    friction = Scenario().friction
    drake = Replayer(trial, engine="drake").run(friction)
    replayer = Replayer(trial, engine="compiled")
    run = min((replayer.run(friction) for _ in range(args.repeats + 1)), key=lambda r: r.wall_time_s)
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(8):
        replayer.run_resampled(friction, None, rng)
    batch = time.perf_counter() - start
    scenario = replay_scenario(trial, friction, None, replayer.numerics)
    # Every coordinate a diagnosis fits that has a sensitivity: the friction and the differentiable effects'.
    names = [
        *FRICTION_NAMES,
        *(p.key for e in LIBRARY.values() if e.differentiable and not e.discrepancy for p in e.coordinate_space()),
    ]
    replayer.session.simulate(scenario, initial=replayer.initial, sensitivities=names[:1])
    derivatives = (
        replayer.session.simulate(scenario, initial=replayer.initial, sensitivities=names).wall_time_s / run.wall_time_s
    )
    apart = float(moved(run.final_head_xy, drake.final_head_xy, run.head_xy[0]))
    print(
        f"replay: {run.t[-1]:.2f} s trial in {run.wall_time_s:.3f} s compiled, {drake.wall_time_s:.2f} s Drake "
        f"({apart:.1e}% apart); 8 bootstrap replays in {batch:.2f} s",
        flush=True,
    )
    return [
        ("10 s replay, Drake wall (s)", drake.wall_time_s, "", None),
        ("10 s replay, compiled wall (s)", run.wall_time_s, "<= 0.15", run.wall_time_s <= 0.15),
        ("10 s replay, Drake / compiled", drake.wall_time_s / run.wall_time_s, "", None),
        ("8 bootstrap replays, compiled, one process (s)", batch, "<= 1", batch <= 1.0),
        (
            f"10 s replay with d/d all {len(names)} friction and effect coordinates / replay",
            derivatives,
            "<= 3",
            derivatives <= 3,
        ),
    ]


def batch(args) -> list:
    from rc1_drake.sweep import make_jobs, run_sweep, single_failure_sets

    jobs = make_jobs(failure_sets=single_failure_sets(), trials=5, seed=0)
    rate = {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers in sorted({1, args.workers}):
            start = time.perf_counter()
            with make_executor(workers=workers) as executor:
                rows = run_sweep(jobs, Path(tmp) / f"sweep{workers}.jsonl", executor=executor, progress=False)
            wall = time.perf_counter() - start
            failed = sum(r["status"] != "ok" for r in rows)
            rate[workers] = len(jobs) / wall
            print(
                f"batch: {len(jobs)} runs on {workers} worker(s) in {wall:.1f} s ({rate[workers]:.2f} runs/s, "
                f"{failed} failed)",
                flush=True,
            )
    wall = len(jobs) / rate[args.workers]
    scaling = rate[args.workers] / rate[1]
    return [
        (f"paper sweep, 70 runs on {args.workers} workers (s)", wall, "<= 20", wall <= 20),
        ("paper sweep, runs/s on 1 worker", rate[1], "", None),
        (f"paper sweep, runs/s on {args.workers} workers", rate[args.workers], "", None),
        (f"paper sweep, scaling 1 -> {args.workers} workers", scaling, ">= 1.8", scaling >= 1.8),
    ]


def identification(args) -> list:
    from rc1_drake.identify import Eq6Objective, avs, fit_program, identify_equation_error, screen
    from rc1_drake.measurements import load_campaign
    from rc1_drake.synthesize import IDENTIFICATION_DESIGN, synthesize_campaign
    from rc1_drake.sysid.objective import CampaignResiduals
    from rc1_drake.sysid.parameters import PAPER_MANUAL

    with tempfile.TemporaryDirectory() as tmp, make_executor(workers=args.workers) as executor:
        synthesize_campaign(
            Path(tmp) / "c",
            design=IDENTIFICATION_DESIGN,
            seed=8,
            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=3.0),
        )
        campaign = load_campaign(Path(tmp) / "c")
        score = Eq6Objective(campaign.trials, executor=executor)  # scoring only: not counted

        start = time.perf_counter()
        objective = Eq6Objective(campaign.trials, executor=executor)
        result = avs(objective, start=PAPER_MANUAL, iterations=10)
        avs_wall, target = time.perf_counter() - start, result.error
        print(
            f"identification: AVS {result.start_error:.2f}% -> {target:.2f}% in {result.simulations} trial "
            f"simulations, {avs_wall:.0f} s",
            flush=True,
        )

        start = time.perf_counter()
        residuals = CampaignResiduals(campaign.trials, executor=executor)
        fitted = screen(residuals, PAPER_MANUAL)[0]
        reached = []

        def on_iteration(friction, simulations):
            if not reached and score(friction) <= target:
                reached.append((simulations, time.perf_counter() - start))

        fit_program(residuals, start=PAPER_MANUAL, parameters=fitted, max_iterations=10, on_iteration=on_iteration)
        program = reached[0] if reached else (residuals.simulations, float("inf"))
        print(
            f"identification: program fit reached {target:.2f}% after "
            f"{program[0] if reached else 'never (of ' + str(program[0]) + ')'} trial simulations",
            flush=True,
        )

        start = time.perf_counter()
        equation = identify_equation_error(campaign)
        eq_wall = time.perf_counter() - start
        eq_error = score(equation.friction)
        print(
            f"identification: equation error {eq_error:.2f}% with 0 trial simulations in {eq_wall:.1f} s "
            f"({equation.samples_used} of {equation.samples} camera samples passed its slip gate)",
            flush=True,
        )
    sims = result.simulations
    return [
        ("AVS (10 iterations): trial simulations", sims, "", None),
        ("AVS: wall (s)", avs_wall, "", None),
        (
            "program fit: simulations to AVS's error",
            program[0] if reached else float("inf"),
            f"<= {sims / 5:.0f}",
            bool(reached) and program[0] <= sims / 5,
        ),
        ("program fit: wall to AVS's error (s)", program[1], "", None),
        ("equation error: simulations (Eq. 6 error reached)", 0, f"<= {sims / 5:.0f}", eq_error <= target),
        ("equation error: Eq. 6 error (%) vs AVS's", eq_error, f"<= {target:.2f}", eq_error <= target),
    ]


def one_replay_s(repeats: int) -> float:
    """The shipped 10 s trial's compiled replay, best of `repeats` after a first that compiles: the machine's unit."""
    from rc1_drake.measurements import load_trial
    from rc1_drake.replay import Replayer

    replayer = Replayer(load_trial(TRIAL))
    return min(replayer.run(Scenario().friction).wall_time_s for _ in range(repeats + 1))


def diagnosis(args) -> list:
    from rc1_drake.diagnose import diagnose
    from rc1_drake.measurements import load_campaign

    campaign = load_campaign(REPO_ROOT / "data" / "paper_campaign")
    one = one_replay_s(args.repeats)
    start = time.perf_counter()
    result = diagnose(campaign, workers=args.workers)
    wall = time.perf_counter() - start
    print(
        f"diagnosis: {len(campaign.trials)} trials, {result.simulations} replays, {wall:.0f} s ({wall / one:.0f} "
        f"single 10 s replays of {one:.3f} s), verdict {result.verdict}",
        flush=True,
    )
    return [
        (f"diagnosis, every candidate, {len(campaign.trials)} trials (min)", wall / 60, "<= 2", wall <= 120),
        ("diagnosis: replays", result.simulations, "", None),
        ("diagnosis / one 10 s replay on this machine (for another machine)", wall / one, "", None),
    ]


def plan(args) -> list:
    """`rc1 design`'s plan (budget 4, 8 drawn designs beside the paper's kinds, one check replicate) from the shipped
    campaign's diagnosis: the plan's own time, the diagnosis before it not counted."""
    from rc1_drake.cli.options import jsonable
    from rc1_drake.design import design_trials
    from rc1_drake.diagnose import diagnose
    from rc1_drake.measurements import load_campaign

    one = one_replay_s(args.repeats)
    result = diagnose(load_campaign(REPO_ROOT / "data" / "paper_campaign"), workers=args.workers, probe_study=False)
    data = json.loads(json.dumps(result.to_json(), default=jsonable))
    start = time.perf_counter()
    made = design_trials(diagnosis=data, budget=4, candidates=8, replicates=1, workers=args.workers)
    wall = time.perf_counter() - start
    print(f"plan: {made.considered} designs, {made.simulations} simulations, {wall:.0f} s", flush=True)
    return [
        (f"a plan of 4 trials among {made.considered} designs (min)", wall / 60, "<= 3", wall <= 180),
        ("a plan / one 10 s replay on this machine", wall / one, "", None),
    ]


FOREIGN = REPO_ROOT / "benchmarks" / "out" / "speed_foreign"
FOREIGN_STOP_NM_PER_RAD = 50.0


def foreign_campaign():
    """The foreign section's campaign (module docstring), made on first use."""
    from rc1_drake.measurements import load_campaign
    from rc1_drake.synthesize import Case, synthesize_campaign

    partial = FOREIGN.with_name(FOREIGN.name + ".partial")
    if not FOREIGN.exists():  # made whole in `partial` (an interrupted one started again), then renamed
        shutil.rmtree(partial, ignore_errors=True)
        design = [Case([], 5), Case([7], 5), Case([13], 5), Case([7], 5, bias_deg=-0.9)]
        synthesize_campaign(partial, design=design, seed=67, sample_period_s=0.02, truth_model="reference",
                            effects={"reference_stop_Nm_per_rad": FOREIGN_STOP_NM_PER_RAD},
                            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=10.0))  # fmt: skip
        partial.rename(FOREIGN)
    return load_campaign(FOREIGN)


def foreign(args) -> list:
    from rc1_drake.diagnose import diagnose

    campaign = foreign_campaign()
    one = one_replay_s(args.repeats)
    start = time.perf_counter()
    result = diagnose(campaign, workers=args.workers, start_rates="fit")
    wall = time.perf_counter() - start
    print(f"foreign diagnosis: {len(campaign.trials)} trials, {result.simulations} replays, {wall:.0f} s, verdict "
          f"{result.verdict}", flush=True)  # fmt: skip
    return [
        (f"diagnosis of {len(campaign.trials)} foreign trials, starts fitted (min)", wall / 60, "<= 3", wall <= 180),
        ("foreign diagnosis: replays", result.simulations, "", None),
        ("foreign diagnosis / one 10 s replay on this machine", wall / one, "", None),
    ]


SPEED_PAGE, SPEED_BLOCK, WRITER = REPO_ROOT / "docs" / "speed.md", "speed-table", "benchmarks/speed.py --markdown"


def write_speed_table(rows, machine) -> None:
    """Write this run's figures into docs/speed.md's table: a figure measured again replaces its row, the others
    stay (so one section can be re-run alone), new ones are appended."""
    fresh = {n: f"| {n} | {v:.3g} | {t} | {'' if m is None else ('yes' if m else 'no')} |" for n, v, t, m in rows}
    old = read_block(SPEED_PAGE, SPEED_BLOCK, WRITER).splitlines()
    kept = [line for line in old if line.startswith("| ") and not line.startswith("| figure")]
    table = [fresh.pop(line.split(" | ")[0][2:], line) for line in kept] + list(fresh.values())
    lines = [
        f"Measured on {machine} by `python benchmarks/speed.py --markdown` (last run {time.strftime('%Y-%m-%d')}):",
        "",
        "| figure | measured | target | met |",
        "|---|---|---|---|",
    ]
    write_block(SPEED_PAGE, SPEED_BLOCK, WRITER, "\n".join(lines + table))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated, of {', '.join(SECTIONS)}")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", default=None, help="also write the table here")
    parser.add_argument("--markdown", action="store_true", help="write the table into docs/speed.md (its markers)")
    args = parser.parse_args()
    chosen = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [s for s in chosen if s not in SECTIONS]
    if unknown:
        parser.error(f"--only: unknown section {unknown[0]!r} (choose from {', '.join(SECTIONS)})")
    if args.markdown:
        check_block(SPEED_PAGE, SPEED_BLOCK, WRITER)
    machine = (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}"
    )
    print(f"machine: {machine}")
    use_engine("compiled")  # batch sections: the compiled engine, as the batch commands
    rows = []
    for section in chosen:
        rows += globals()[section](args)
    print(f"\n{'figure':52} {'measured':>10} {'target':>10}  met")
    for name, value, target, met in rows:
        print(f"{name:52} {value:>10.3g} {target:>10}  {'' if met is None else ('yes' if met else 'NO')}")
    if args.markdown:
        write_speed_table(rows, machine)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(
            json.dumps(
                {
                    "machine": machine,
                    "rows": [
                        {"figure": n, "measured": float(v), "target": t, "met": None if m is None else bool(m)}
                        for n, v, t, m in rows
                    ],
                },
                indent=1,
            )
            + "\n"
        )


if __name__ == "__main__":
    main()
