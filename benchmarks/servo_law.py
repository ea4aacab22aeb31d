"""Issue 41: the working servos' law (no integrator, Kp swept) as the mechanism of the paper's circling, scored on
every finding of section 4, one process.

    python benchmarks/servo_law.py [--settings NAME ...] [--trials 5] [--jsonl PATH]
    python benchmarks/servo_law.py --engine-check NAME [--case J2] [--trials 5]

Each setting (SETTINGS: servo gains, friction, effects) runs `rc1 reproduce`'s whole table (reproduce.paper_jobs:
no failure, J1-J13 failed, J7+bias; the paper's start, stop rule and 60 s limit) on the compiled engine, in this
process, scored by reproduce.assemble. One row per setting: findings reproduced, J2's revolutions / direction /
diameter, J3-J6's circling trials and diameters, the final head y of the nominal, J7 and J7+bias, and the intact
snake's tracking: RMS and worst |q - commanded| over its runs (what the paper's potentiometers would have shown).
--engine-check runs one case's trials of a setting on the compiled engine and on the Drake Diagram and prints each
pair's scores and how far apart their head paths are (at the Drake run's log times, over the shorter run).
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
from doc_blocks import append_row  # benchmarks/ is on the path when this runs

from rc1_drake.config import Friction, Servo
from rc1_drake.effects import commanded_gait
from rc1_drake.engine import make_session
from rc1_drake.gait import serpenoid
from rc1_drake.reproduce import assemble, paper_jobs, run_trial, score_trial
from rc1_drake.sweep import simulate_job


def _s(servo=None, friction=None, effects=None) -> dict:
    return dict(servo=servo or {}, friction=friction or {}, effects=effects or {})


P_ONLY = {"ki_Nm_per_rad_s": 0.0}  # a hobby servo's proportional loop: no integrator, the model's Kd
# name -> change of the paper's model; the bounds are the brief's plausible ranges (docs/findings.md).
SETTINGS = {
    "model": _s(),
    **{f"p{kp:g}": _s(servo=P_ONLY | {"kp_Nm_per_rad": kp}) for kp in (2.0, 3.0, 5.0, 10.0)},
}
COMBOS = {
    "cantilever": _s(effects={"head_on_wheel2": 1.0}),
    "stop20": _s(effects={"stop_compliance_rad_per_Nm": 0.05}),
    "mu_lat1": _s(friction={"mu_lat": 1.0}),
    "mu_lat2.5": _s(friction={"mu_lat": 2.5}),
    "c_lat2": _s(friction={"c_lat": 2.0}),
    "c_lat10": _s(friction={"c_lat": 10.0}),
    "tau0.8": _s(servo={"torque_limit_Nm": 0.8}),
    "tau1.0": _s(servo={"torque_limit_Nm": 1.0}),
}


def setting_of(name: str) -> dict:
    """SETTINGS[name], or BASE+COMBO[+COMBO...] (e.g. p3+cantilever+mu_lat1): the base with each change added."""
    base, *combos = name.split("+")
    setting = SETTINGS[base]
    for combo in combos:
        setting = {k: setting[k] | COMBOS[combo][k] for k in setting}
    return setting


def model_of(setting: dict) -> tuple:
    """(servo, friction, effects) of a setting."""
    servo = dataclasses.replace(Servo(), **setting["servo"])
    return servo, dataclasses.replace(Friction(), **setting["friction"]), dict(setting["effects"])


def tracking_deg(runs) -> tuple[float, float]:
    """RMS and worst |q - commanded| (deg) over every joint and sample of intact-snake runs."""
    errors = []
    for run in runs:
        gait = commanded_gait(run.scenario.gait, run.scenario.effects)
        commanded = np.array([serpenoid(t, gait)[0] for t in run.t])
        errors.append((run.q - commanded).ravel())
    e = np.degrees(np.concatenate(errors))
    return float(np.sqrt(np.mean(e**2))), float(np.abs(e).max())


def measure(name: str, *, trials: int) -> dict:
    servo, friction, effects = model_of(setting_of(name))
    jobs = paper_jobs(trials=trials, friction=friction, effects=effects, servo=servo)
    result = assemble(traces=[run_trial(job) for job in jobs])
    rms, worst = tracking_deg([simulate_job(job) for job in jobs if job.label == "none"])
    cases = result.cases
    return {
        "setting": name,
        "servo": dataclasses.asdict(servo),
        "friction": setting_of(name)["friction"],
        "effects": effects,
        "reproduced": sum(bool(v.reproduced) for v in result.scored),
        "scored": len(result.scored),
        "cases": {label: _case(c) for label, c in cases.items()},
        "tracking_rms_deg": rms,
        "tracking_max_deg": worst,
        "failed_findings": [f"{v.finding.label}: {v.finding.claim}" for v in result.scored if not v.reproduced],
    }


def _case(case) -> dict:
    return {
        "counts": case.outcome_counts,
        "direction": case.direction,
        "revolutions": case.revolutions,
        "diameter_m": case.circle_diameter_m,
        "final_y_m": case.final_y_m,
    }


def format_row(r: dict) -> str:
    c = r["cases"]
    j2 = c["J2"]
    d2 = "-" if j2["diameter_m"] is None else f"{j2['diameter_m']:.2f}"
    mid = " ".join(f"{c[f'J{j}']['counts'].get('circling', 0)}/" + _d(c[f"J{j}"]["diameter_m"]) for j in range(3, 7))
    ys = " ".join(f"{np.mean(c[k]['final_y_m']):+.2f}" for k in ("none", "J7", "J7+bias"))
    j2_circled = f"{j2['counts'].get('circling', 0)}/{sum(j2['counts'].values())}"
    return (f"{r['setting']:<18}{r['reproduced']:>3}/{r['scored']:<3}{j2_circled} "
            f"{j2['revolutions']:>5.2f} {j2['direction'] or '-':<4}{d2:>5}  {mid:<34}{ys:<20}"
            f"{r['tracking_rms_deg']:>5.2f}{r['tracking_max_deg']:>6.1f}")  # fmt: skip


def _d(value) -> str:
    return "-" if value is None else f"{value:.2f}"


HEADER = (f"{'setting':<18}{'found':<7}{'J2 circ rev dir diam':<24}{'J3-J6 circling/diam m':<34}"
          f"{'y none J7 J7+b':<20}{'rms':>5}{'max':>6}")  # fmt: skip


def path_gap_m(a, b) -> tuple[float, float]:
    """Mean and worst distance between two runs' head paths at b's log times, over the shorter run."""
    t = b.t[b.t <= a.t[-1]]
    xa = np.column_stack([np.interp(t, a.t, a.head_xy[:, k]) for k in range(2)])
    d = np.linalg.norm(xa - b.head_xy[: len(t)], axis=1)
    return float(d.mean()), float(d.max())


def engine_check(name: str, *, case: str, trials: int) -> None:
    """The case's trials of a setting on both engines: outcome, revolutions, diameter, final xy, path gap."""
    servo, friction, effects = model_of(setting_of(name))
    joints = [int(case[1:])] if case.startswith("J") else []
    jobs = [j for j in paper_jobs(joints=joints, trials=trials, friction=friction, effects=effects, servo=servo)
            if j.label == case]  # fmt: skip
    for job in jobs:  # a session per trial: the trial's start phase is part of the Drake Diagram
        runs = {e: make_session(job.scenario, engine=e).simulate(job.scenario) for e in ("compiled", "drake")}
        for e, run in runs.items():
            sc = score_trial(run=run)
            x, y = sc.final_head_xy_m
            turn = f"{sc.outcome:<12}{sc.revolutions:5.2f} {sc.direction or '-':<4}{_d(sc.circle_diameter_m):>6} m"
            print(f"{name} {case} trial {job.trial} {e:<9}{turn}  end ({x:+.2f}, {y:+.2f}) m at {sc.t_final_s:.1f} s")
        mean, worst = path_gap_m(runs["compiled"], runs["drake"])
        print(f"  head paths apart: mean {mean * 100:.1f} cm, worst {worst * 100:.1f} cm", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--settings",
        nargs="*",
        default=list(SETTINGS),
        help=f"{', '.join(SETTINGS)}, or BASE+CHANGE[+CHANGE] of {', '.join(COMBOS)}",
    )
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--jsonl", help="append each setting's row as one JSON line")
    parser.add_argument("--engine-check", metavar="SETTING", help="compare the engines on one setting's --case")
    parser.add_argument("--case", default="J2")
    args = parser.parse_args()
    if args.engine_check:
        return engine_check(args.engine_check, case=args.case, trials=args.trials)
    print(HEADER, flush=True)
    for name in args.settings:
        started = time.perf_counter()
        r = measure(name, trials=args.trials)
        print(format_row(r) + f"  ({time.perf_counter() - started:.0f} s)", flush=True)
        if args.jsonl:
            append_row(Path(args.jsonl), r)


if __name__ == "__main__":
    main()
