"""Issue 41's ring hypothesis: does a uniform bias B on the working joints make the J2 snake circle 0.56 m (L / pi)?

    python benchmarks/ring.py [--cases none J2] [--bias-deg -5 -10 ...] [--amplitude-deg 38 ...] [--trials 2]
                              [--per-joint] [--servo KEY=VALUE ...]

Runs the paper's cases (reproduce.paper_jobs: its start, the 3.18 m line, 2 revolutions, 60 s) with every joint's
bias set to B (Eq. 7; a failed joint is free, so its bias does nothing) and optionally the amplitude A changed, on
the compiled engine, one process. Per (case, A, B): outcomes, direction, revolutions, mean head circle diameter
(metrics.circle_diameter over complete turns: of the circling trials, and `any1` of every trial with one complete
turn), time to stop and seconds per revolution, and the working joints' mean measured
angle q over the run after its first gait period (the bend the body actually held), with the time at a limit, and
the failed joint's mean angle.
A ring of 14 modules closed by the body needs 360 / 14 = 25.7 deg per joint and puts the head on a 0.56 m circle.
"""

import argparse
import dataclasses
import math
import time

import numpy as np
from mechanisms import held_by_servo, trials_summary

from rc1_drake.config import JOINT_LIMIT_DEG, NUM_JOINTS, Servo
from rc1_drake.engine import make_session
from rc1_drake.reproduce import GAIT_PERIOD_S, paper_jobs, score_trial

PITCH_M = 0.125  # module pitch: 14 modules over 1.75 m
RING_BEND_DEG = 360.0 / (NUM_JOINTS + 1)  # the closed ring: 14 equal turns of the chain
RING_DIAMETER_M = PITCH_M / math.sin(math.radians(RING_BEND_DEG) / 2)  # circumcircle of the 14-gon: 0.562 m
PAPER_DIAMETER_M = 0.56  # Sec. 4, Fig. 10


def jobs_of(*, case: str, bias_deg: float, amplitude_deg: float, trials: int, servo: dict, hold_deg=None) -> list:
    """The paper's jobs of `case` (none or Jk) with the gait's bias and amplitude set on every joint; hold_deg: the
    case's joint is not failed but held by its servo at this angle (a diagnostic, as mechanisms.py's hold)."""
    joints = [int(case[1:])] if case.startswith("J") else []
    jobs = paper_jobs(joints=joints, trials=trials, servo=dataclasses.replace(Servo(), **servo))
    out = []
    for job in (j for j in jobs if j.label == case):
        gait = dataclasses.replace(job.scenario.gait, bias_deg=bias_deg, amplitude_deg=amplitude_deg)
        failures = job.scenario.failures
        if hold_deg is not None:
            gait, failures = held_by_servo(gait, failures, hold_deg)
        out.append(dataclasses.replace(job, scenario=dataclasses.replace(job.scenario, gait=gait, failures=failures)))
    return out


def held_bend(run, working) -> tuple[np.ndarray, float]:
    """Per-joint mean q (rad, all 13) over the run after its first gait period, and the fraction of the working
    joints' samples at a limit."""
    settled = run.t >= min(GAIT_PERIOD_S, run.t[-1] / 2)  # past the start transient, or its second half
    q = run.q[settled]
    at_limit = np.abs(q[:, working]) >= math.radians(JOINT_LIMIT_DEG) - 1e-3  # within 0.06 deg of +-38 deg
    return q.mean(axis=0), float(at_limit.mean())


def measure(session, *, case, bias_deg, amplitude_deg, trials, servo, hold_deg=None) -> dict:
    """One row: the case's trials at (A, B), scored as rc1 reproduce, and the bend they held."""
    working = [j for j in range(NUM_JOINTS) if case != f"J{j + 1}"]
    scores, bends, limits = [], [], []
    jobs = jobs_of(case=case, bias_deg=bias_deg, amplitude_deg=amplitude_deg, trials=trials, servo=servo,
                   hold_deg=hold_deg)  # fmt: skip
    for job in jobs:
        run = session.simulate(job.scenario).until_event()
        scores.append(score_trial(run=run))
        bend, at_limit = held_bend(run, working)
        bends.append(bend)
        limits.append(at_limit)
    d = [s.circle_diameter_m for s in scores if s.outcome == "circling" and s.circle_diameter_m]
    turned = [s.circle_diameter_m for s in scores if s.circle_diameter_m]  # any trial with a complete turn
    per_joint = np.degrees(np.mean(bends, axis=0))
    failed = [j for j in range(NUM_JOINTS) if j not in working]
    return {
        "case": case,
        "A_deg": amplitude_deg,
        "B_deg": bias_deg,
        **trials_summary(scores),
        "diam_m": float(np.mean(d)) if d else None,
        "turned_diam_m": float(np.mean(turned)) if turned else None,
        "s_per_rev": float(np.mean([s.t_final_s / s.revolutions if s.revolutions else math.inf for s in scores])),
        "bend_deg": float(per_joint[working].mean()),
        "failed_q_deg": float(per_joint[failed].mean()) if failed else None,
        "at_limit": float(np.mean(limits)),
        "per_joint_deg": dict(zip(range(1, NUM_JOINTS + 1), per_joint.round(1).tolist(), strict=True)),
    }


HEADER = f"{'case':<6}{'A deg':>6}{'B deg':>7}  {'outcomes':<26}{'direction':<10}{'rev':>5}{'diam m':>8}{'any1':>6}"
HEADER += f"{'t s':>6}{'s/rev':>7}{'bend deg':>9}{'at limit':>9}{'failed q':>9}"


def format_row(r: dict) -> str:
    diam, turned = ("-" if v is None else f"{v:.2f}" for v in (r["diam_m"], r["turned_diam_m"]))
    failed = "-" if r["failed_q_deg"] is None else f"{r['failed_q_deg']:+.1f}"
    return (f"{r['case']:<6}{r['A_deg']:>6.1f}{r['B_deg']:>+7.1f}  {r['outcomes']:<26}{r['dir']:<10}{r['rev']:>5.2f}"
            f"{diam:>8}{turned:>6}{r['t_s']:>6.1f}{r['s_per_rev']:>7.1f}{r['bend_deg']:>+9.1f}"
            f"{r['at_limit']:>9.1%}{failed:>9}")  # fmt: skip


def parse_servo(items) -> dict:
    """KEY=VALUE pairs of config.Servo fields."""
    known = {f.name for f in dataclasses.fields(Servo)}
    out = {}
    for item in items:
        key, _, value = item.partition("=")
        if key not in known:
            raise SystemExit(f"--servo: unknown field '{key}' (known: {', '.join(sorted(known))})")
        out[key] = float(value)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=["J2", "none"])
    parser.add_argument("--bias-deg", nargs="*", type=float, default=[0, -5, -10, -15, -20, -25, -30, 5, 10, 20, 30])
    parser.add_argument("--amplitude-deg", nargs="*", type=float, default=[38.0])
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--within-limits", action="store_true", help="A = min(A, 38 - |B|): the command inside +-38")
    parser.add_argument("--hold-deg", type=float, help="the case's joint held at this angle instead of failed")
    parser.add_argument("--per-joint", action="store_true", help="also print each working joint's mean q (deg)")
    parser.add_argument("--servo", nargs="*", default=[], help="config.Servo fields, e.g. kp_Nm_per_rad=5")
    args = parser.parse_args()
    servo = parse_servo(args.servo)
    session = make_session(None, engine="compiled")
    print(f"ring: {RING_BEND_DEG:.1f} deg per joint, head circle {RING_DIAMETER_M:.3f} m; servo {servo or 'paper'}")
    print(HEADER, flush=True)
    for case in args.cases:
        for amplitude in args.amplitude_deg:
            for bias in args.bias_deg:
                # with --within-limits the command's peaks A + |B| stay at the joint limit
                a = min(amplitude, JOINT_LIMIT_DEG - abs(bias)) if args.within_limits else amplitude
                started = time.perf_counter()
                r = measure(session, case=case, bias_deg=bias, amplitude_deg=a, trials=args.trials, servo=servo,
                            hold_deg=args.hold_deg)  # fmt: skip
                print(format_row(r) + f"  ({time.perf_counter() - started:.0f} s)", flush=True)
                if args.per_joint:
                    print("      " + " ".join(f"J{j}:{v:+.1f}" for j, v in r["per_joint_deg"].items()), flush=True)


if __name__ == "__main__":
    main()
