"""Screen candidate mechanisms of the paper's J2 circling (issue 41), alone and together, on one process.

    python benchmarks/mechanisms.py [--settings NAME ...] [--cases none J2 J7] [--trials 2] [--time-limit-s 60]

Each setting is a named change of the paper's model or of scenarios/paper_findings.yaml's (SETTINGS: friction,
effects, servo, failure instant, start phase, a bias); each runs the paper's cases (reproduce.paper_jobs: its start,
its stop rule) on the compiled engine and is scored as `rc1 reproduce` scores them (reproduce.score_trial). It
prints one row per setting and case: outcomes, direction, revolutions, circle diameter (metrics.circle_diameter over
complete turns), final head y and time. Effect values are not validated against the library's bounds here: a screen
may look past them (say so).
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from rc1_drake.config import Friction, JointGait, Servo
from rc1_drake.engine import make_session
from rc1_drake.reproduce import paper_jobs, score_trial
from rc1_drake.scenarios import load_scenario

PAPER = Friction()
FINDINGS_FILE = Path(__file__).resolve().parents[1] / "scenarios" / "paper_findings.yaml"


def _s(friction=None, effects=None, servo=None, fail_s=0.0, phase_deg=None, hold_deg=None, bias_deg=0.0):
    """hold_deg: the failed joint is not failed but held by its servo at this angle (a diagnostic, not a failure);
    bias_deg: a bias added to every working joint's command."""
    return dict(friction=friction or {}, effects=effects or {}, servo=servo or {}, fail_s=fail_s, phase_deg=phase_deg,
                hold_deg=hold_deg, bias_deg=bias_deg)  # fmt: skip


def _findings(**changes):
    """The model of scenarios/paper_findings.yaml (P-only servos, the head on wheel 2, fitted), with `changes`."""
    s = load_scenario("nominal", filename=FINDINGS_FILE)
    servo = {k: getattr(s.servo, k) for k in ("kp_Nm_per_rad", "ki_Nm_per_rad_s")}
    friction = {k: v for k, v in dataclasses.asdict(s.friction).items() if v != getattr(PAPER, k)}
    setting = _s(friction=friction, effects=dict(s.effects), servo=servo)
    for key, value in changes.items():
        setting[key] = {**setting[key], **value} if isinstance(value, dict) else value
    return setting


# The working servo's motor line (HS-5645MG at 6 V: 1.19 N m stall, 0.18 s/60 deg = 5.8 rad/s no load) leaves
# 1.19 (1 - 1.62 / 5.8) = 0.86 N m at the gait's peak joint speed (38 deg x 140 deg/s = 1.62 rad/s): a torque limit of
# 0.86 N m brackets the speed limit from below. Its deadband (8 us of a ~1800 us stroke, ~0.8 deg) lets each joint
# stand anywhere within +-0.4 deg of its command: a bias of 0.4 deg on every joint brackets it.
MOTOR_LINE_NM = 0.86
DEADBAND_HALF_DEG = 0.4


# name -> change of the paper's model; the physical argument and bound of each is in docs/paper.md.
SETTINGS = {
    "paper": _s(),
    "hold_-38": _s(hold_deg=-38.0),
    "hold_-38_c_lat_20": _s(hold_deg=-38.0, friction={"c_lat": 20.0}),
    "stop_20": _s(effects={"stop_compliance_rad_per_Nm": 0.05}),
    "stop_5": _s(effects={"stop_compliance_rad_per_Nm": 0.2, "stop_d_Nm_s_per_rad": 0.02}),
    "stop_100": _s(effects={"stop_compliance_rad_per_Nm": 0.01, "stop_d_Nm_s_per_rad": 0.5}),
    "stop_20_coul_1": _s(effects={"stop_compliance_rad_per_Nm": 0.05, "joint_coulomb_Nm": 1.0}),
    "cantilever_1": _s(effects={"head_on_wheel2": 1.0}),
    "cantilever_2": _s(effects={"head_on_wheel2": 2.0}),
    "cantilever_2_stop": _s(effects={"head_on_wheel2": 2.0, "stop_compliance_rad_per_Nm": 0.05}),
    "head_drag_2_stop": _s(effects={"head_drag_mu": 2.0, "stop_compliance_rad_per_Nm": 0.05}),
    "mu_lat_2.5_cantilever_1": _s(friction={"mu_lat": 2.5}, effects={"head_on_wheel2": 1.0}),
    "mu_lat_2.5_coulomb_1": _s(friction={"mu_lat": 2.5}, effects={"joint_coulomb_Nm": 1.0}),
    "c_lat_10_cantilever_2": _s(friction={"c_lat": 10.0}, effects={"head_on_wheel2": 2.0}),
    "head_drag_1": _s(effects={"head_drag_mu": 1.0}),
    "coulomb_0.5": _s(effects={"joint_coulomb_Nm": 0.5}),
    "coulomb_1": _s(effects={"joint_coulomb_Nm": 1.0}),
    "coulomb_2": _s(effects={"joint_coulomb_Nm": 2.0}),
    "servo_2Nm": _s(servo={"torque_limit_Nm": 2.0}),
    "servo_stiff": _s(servo={"torque_limit_Nm": 20.0, "kp_Nm_per_rad": 200.0, "kd_Nm_s_per_rad": 2.0}),
    "servo_0.8Nm": _s(servo={"torque_limit_Nm": 0.8}),
    # A hobby servo is a P(D) loop with no integrator: the load's steady error stays (issue 41, benchmarks/ring.py).
    "servo_p_only": _s(servo={"ki_Nm_per_rad_s": 0.0}),
    "servo_p_only_kp_5": _s(servo={"ki_Nm_per_rad_s": 0.0, "kp_Nm_per_rad": 5.0}),
    "servo_p_only_kp_3": _s(servo={"ki_Nm_per_rad_s": 0.0, "kp_Nm_per_rad": 3.0}),
    "fail_1.3s": _s(fail_s=1.3),
    "phase_90": _s(phase_deg=90.0),
    "phase_180": _s(phase_deg=180.0),
    "phase_270": _s(phase_deg=270.0),
    "mu_lat_2.5": _s(friction={"mu_lat": 2.5}),
    "c_lat_10": _s(friction={"c_lat": 10.0}),
    "mu_long_0.05": _s(friction={"mu_long": 0.05, "c_long": 0.05}),
    "c_joint_0.5": _s(friction={"c_joint": 0.5}),
    "motor_line": _s(servo={"torque_limit_Nm": MOTOR_LINE_NM}),
    "deadband_+": _s(bias_deg=DEADBAND_HALF_DEG),
    "deadband_-": _s(bias_deg=-DEADBAND_HALF_DEG),
    # RC1's power tether at the tail (effects.TailTether).
    "tether_0.5": _s(effects={"tail_tether_N": 0.5}),
    "tether_1": _s(effects={"tail_tether_N": 1.0}),
    "tether_2": _s(effects={"tail_tether_N": 2.0}),
    "findings": _findings(),
    "findings_motor_line": _findings(servo={"torque_limit_Nm": MOTOR_LINE_NM}),
    "findings_deadband_+": _findings(bias_deg=DEADBAND_HALF_DEG),
    "findings_deadband_-": _findings(bias_deg=-DEADBAND_HALF_DEG),
    "findings_tether_1": _findings(effects={"tail_tether_N": 1.0}),
}


def jobs_of(setting: dict, *, cases, trials: int, time_limit_s: float) -> list:
    """The paper's jobs of `cases` with the setting's changes made to each scenario."""
    joints = sorted({int(c[1:]) for c in cases if c.startswith("J")})
    friction = dataclasses.replace(PAPER, **setting["friction"])
    servo = dataclasses.replace(Servo(), **setting["servo"])
    jobs = paper_jobs(joints=joints, trials=trials, friction=friction, effects=setting["effects"], servo=servo,
                      time_limit_s=time_limit_s)  # fmt: skip
    out = []
    for job in (j for j in jobs if j.label in cases):
        s = job.scenario
        failures = [dataclasses.replace(f, time_s=setting["fail_s"]) for f in s.failures]
        gait = dataclasses.replace(s.gait, bias_deg=s.gait.bias_deg + setting["bias_deg"])
        if setting["phase_deg"] is not None:  # the wave's start phase moved, the trial's jitter kept
            gait = dataclasses.replace(gait, phase_offset_deg=gait.phase_offset_deg + setting["phase_deg"])
        if setting["hold_deg"] is not None:
            gait, failures = held_by_servo(gait, failures, setting["hold_deg"])
        out.append(dataclasses.replace(job, scenario=dataclasses.replace(s, failures=failures, gait=gait)))
    return out


def held_by_servo(gait, failures, hold_deg: float) -> tuple:
    """(gait, failures) with each failed joint not failed but held by its servo at hold_deg (a diagnostic)."""
    held = [JointGait(joint=f.joint, amplitude_deg=0.0, bias_deg=hold_deg) for f in failures]
    return dataclasses.replace(gait, joints=held), []


def trials_summary(scores) -> dict:
    """What a row says of a case's trials (reproduce.score_trial's scores): outcomes, directions, revolutions, time."""
    outcomes = [s.outcome for s in scores]
    return {
        "outcomes": ", ".join(f"{o} {outcomes.count(o)}" for o in dict.fromkeys(outcomes)),
        "dir": "/".join(s.direction or "-" for s in scores),
        "rev": float(np.mean([s.revolutions for s in scores])),
        "t_s": float(np.mean([s.t_final_s for s in scores])),
    }


def screen(name: str, setting: dict, *, session, cases, trials: int, time_limit_s: float) -> list:
    """One row per case of the setting: its trials' scores aggregated."""
    by_case: dict = {}
    for job in jobs_of(setting, cases=cases, trials=trials, time_limit_s=time_limit_s):
        run = session.simulate(job.scenario)
        by_case.setdefault(job.label, []).append((score_trial(run=run), run))
    return [row(name, label, scored) for label, scored in by_case.items()]


def row(name: str, label: str, scored: list) -> dict:
    scores = [s for s, _ in scored]
    d = [s.circle_diameter_m for s in scores if s.circle_diameter_m]
    y = [s.final_head_xy_m[1] for s in scores]
    q2 = np.degrees(np.concatenate([r.q[:, 1] for _, r in scored]))
    return {
        "setting": name,
        "case": label,
        **trials_summary(scores),
        "diam_m": float(np.mean(d)) if d else None,
        "y_m": (min(y), max(y)),
        "q2_mean_deg": float(q2.mean()),
    }


def format_row(r: dict) -> str:
    diam = "-" if r["diam_m"] is None else f"{r['diam_m']:.2f}"
    return (f"{r['setting']:<18}{r['case']:<6}{r['outcomes']:<30}{r['dir']:<16}{r['rev']:>5.2f}{diam:>7}"
            f"{r['y_m'][0]:>+7.2f}..{r['y_m'][1]:<+6.2f}{r['t_s']:>6.1f}{r['q2_mean_deg']:>+7.1f}")  # fmt: skip


HEADER = (
    f"{'setting':<18}{'case':<6}{'outcomes':<30}{'direction':<16}{'rev':>5}{'diam':>7}{'final y m':>15}{'t s':>6}"
    f"{'q2deg':>7}"
)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--settings", nargs="*", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--cases", nargs="*", default=["none", "J2", "J7"])
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--time-limit-s", type=float, default=60.0)
    args = parser.parse_args()
    session = make_session(None, engine="compiled")
    print(HEADER, flush=True)
    for name in args.settings:
        started = time.perf_counter()
        rows = screen(name, SETTINGS[name], session=session, cases=args.cases, trials=args.trials,
                      time_limit_s=args.time_limit_s)  # fmt: skip
        for r in rows:
            print(format_row(r), flush=True)
        print(f"  ({time.perf_counter() - started:.1f} s)", flush=True)


if __name__ == "__main__":
    main()
