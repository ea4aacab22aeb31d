"""The paper's section-4 findings as data, and the model scored against them (`rc1 reproduce`).

FINDINGS holds each claim of section 4 once, with where the paper makes it. score_trial classifies one
head path (circling, turned back, crossed, timed out); score_case aggregates a case's trials; judge marks
a finding reproduced or not. reproduce() runs the paper's cases (no failure, joints 1-13 failed in turn,
J7 with the bias of Fig. 13) from the paper's start, five trials each, and returns a Reproduction.
"""

from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import as_completed

import numpy as np

from .config import Failure, Friction, Servo, Stop
from .metrics import circle_diameter, revolutions

LINE_X_M = 3.18  # Sec. 4: "a line located 3.18m from its starting location"
CIRCLING_REVOLUTIONS = 2.0  # Sec. 4, Fig. 10: "until the head of the snake had made two complete revolutions"
PAPER_TRIALS = 5  # Sec. 4: "Each experiment was carried out five times"
GAIT_PERIOD_S = 360.0 / 140.0  # Sec. 2, Eq. 3: the joints run at 140 deg/s
# Sec. 4, Eq. 7, Fig. 13: B_i = 3.0 (unit not stated; read as degrees, as A_i). It removed J7's drift to -y, so it
# turned the snake left; in this model a positive bias turns it right (README, Conventions): the sign flips.
PAPER_BIAS = 3.0
J7_BIAS_DEG = -PAPER_BIAS
# Two revolutions of biased-gait circles 0.74 / 1.22 / 1.89 / 2.79 m across took 11 / 21 / 32 / 47 s (this model,
# docs/paper.md): 60 s lets a circle up to about 3.5 m across finish; a larger one from the start reaches the line.
TIME_LIMIT_S = 60.0
# Table 2: the worst trial error the paper still called agreement (22.4%, J7+bias), taken for the diameter.
DIAMETER_TOLERANCE = 0.224
# Sec. 4: the nominal's +0.25 to +1 m is a "slightly positive" y, J7's -1 to -2 m a "significant" one.
SLIGHT_DRIFT_M = 1.0
# Backward travel over one gait period beyond this is turning back, not the undulation's wiggle (the intact
# snake advances about 1 m a period: the 3.18 m line in about 10 s, docs/sweeps.md).
TURN_BACK_M = 0.05
HALF_TURN = 0.5  # revolutions: a net heading change past this has a direction (the gait swings the head +-0.15)
OUTCOMES = ("circling", "turned back", "crossed", "timed_out", "error")


@dataclasses.dataclass(frozen=True)
class Finding:
    """One claim of the paper about one or more cases; `checks` are (kind, *values), all must hold."""

    cases: tuple  # case labels ("none", "J2", "J7+bias"); listed under the first
    claim: str
    cite: str
    checks: tuple = ()  # empty: the paper reports nothing to check

    @property
    def label(self) -> str:
        """The row's case: the first, or the span of a finding about a run of joints."""
        return f"{self.cases[0]}-{self.cases[-1]}" if len(self.cases) > 2 else self.cases[0]


def _f(cases, claim, cite, *checks):
    return Finding(cases=tuple(cases), claim=claim, cite=cite, checks=tuple(checks))


FINDINGS = (
    _f(["none"], "reaches the 3.18 m line", "Sec. 4, Fig. 8", ("crossed",)),
    _f(["none"], "final head y +0.25 to +1 m", "Sec. 4, Fig. 8", ("final_y", 0.25, 1.0)),
    _f(["J1"], "not reported (results start at joint 2)", "Sec. 4"),
    _f(["J2"], "circles: two complete revolutions", "Sec. 4, Fig. 10", ("circling",)),
    _f(["J2"], "counter-clockwise seen from above", "Sec. 4, Fig. 10", ("direction", "CCW")),
    _f(["J2"], "mean circle diameter 0.56 m", "Sec. 4, Fig. 10", ("diameter", 0.56)),
    *(_f([f"J{j}"], "circles ('similar circular motions')", "Sec. 4", ("circling",)) for j in range(3, 7)),
    _f([f"J{j}" for j in range(2, 7)], "circle diameters grow from J2 to J6", "Sec. 4", ("diameters_grow",)),
    _f(["J7"], "forward to the line, no turning back", "Sec. 4, Fig. 11", ("crossed",)),
    _f(["J7"], "final head y -2 to -1 m", "Sec. 4, Fig. 11", ("final_y", -2.0, -1.0)),
    *(
        _f([f"J{j}"], "forward, slight y drift (|y| <= 1 m)", "Sec. 4", ("crossed",), ("final_y", -1.0, 1.0))
        for j in range(8, 13)
    ),
    _f(["J13"], "forward, slight y drift (|y| <= 1 m)", "Sec. 4, Fig. 12", ("crossed",), ("final_y", -1.0, 1.0)),
    _f(["J7+bias"], "forward to the line", "Sec. 4, Fig. 13", ("crossed",)),
    _f(["J7+bias", "J7"], "without J7's large -y drift", "Sec. 4, Fig. 13", ("straighter",)),
)


@dataclasses.dataclass
class Trace:
    """What scoring needs of a run (protocol.Run has the same attributes): logs and how it ended."""

    t: np.ndarray  # (N,) s
    head_xy: np.ndarray  # (N, 2) m
    head_yaw: np.ndarray  # (N,) rad
    stop_reason: str  # crossed / circling / timed_out, or "error"
    label: str = ""
    trial: int = 0
    start_modules_xy: np.ndarray | None = None  # (14, 2) m, the modules at t = 0, for the figures
    error: str | None = None


@dataclasses.dataclass
class TrialScore:
    outcome: str  # one of OUTCOMES
    turned_back: bool
    direction: str | None  # CCW / CW (seen from above) once the heading turned past half a revolution
    revolutions: float
    circle_diameter_m: float | None  # over the complete turns; None with less than one
    final_head_xy_m: list
    t_final_s: float
    error: str | None = None


def turned_back(*, t, head_xy, period_s=GAIT_PERIOD_S, threshold_m=TURN_BACK_M) -> bool:
    """True if over some gait period the head went back (toward -x) by more than threshold_m."""
    t, xy = np.asarray(t, dtype=float), np.asarray(head_xy, dtype=float)
    later = np.searchsorted(t, t + period_s)
    has = later < len(t)
    return bool((xy[later[has], 0] - xy[has, 0] < -threshold_m).any())


def score_trial(*, run, line_x_m=LINE_X_M) -> TrialScore:
    """Classify one run (a Trace or a protocol.Run): circling (two revolutions, the paper's stop) before turned
    back (went back toward the start, Sec. 4's "turning back on itself") before crossed and timed_out."""
    if getattr(run, "error", None):
        return TrialScore("error", False, None, math.nan, None, [None, None], math.nan, run.error)
    xy, yaw = np.asarray(run.head_xy, dtype=float), np.asarray(run.head_yaw, dtype=float)
    revs = revolutions(yaw)
    back = turned_back(t=run.t, head_xy=xy)
    crossed = run.stop_reason == "crossed" or xy[-1, 0] >= line_x_m
    if run.stop_reason == "circling" or revs >= CIRCLING_REVOLUTIONS:
        outcome = "circling"
    else:
        outcome = "turned back" if back else "crossed" if crossed else "timed_out"
    turn = np.unwrap(yaw)[-1] - yaw[0]
    diameter = circle_diameter(xy, yaw)
    return TrialScore(
        outcome=outcome,
        turned_back=back,
        direction=None if revs < HALF_TURN else ("CCW" if turn > 0 else "CW"),
        revolutions=float(revs),
        circle_diameter_m=float(diameter) if math.isfinite(diameter) else None,
        final_head_xy_m=[float(xy[-1, 0]), float(xy[-1, 1])],
        t_final_s=float(run.t[-1]),
    )


@dataclasses.dataclass
class CaseScore:
    label: str
    trials: list  # TrialScore per trial

    def count(self, outcome) -> int:
        return sum(s.outcome == outcome for s in self.trials)

    @property
    def outcome_counts(self) -> dict:
        return {o: self.count(o) for o in OUTCOMES if self.count(o)}

    @property
    def outcome(self) -> str:
        """The outcome most trials had (the earlier in OUTCOMES on a tie)."""
        return max(OUTCOMES, key=lambda o: (self.count(o), -OUTCOMES.index(o)))

    @property
    def direction(self) -> str | None:
        turns = [s.direction for s in self.trials if s.direction]
        return max(sorted(set(turns)), key=turns.count) if turns else None

    @property
    def revolutions(self) -> float:
        return _mean([s.revolutions for s in self.trials])

    @property
    def circle_diameter_m(self) -> float | None:
        """Mean over the circling trials; None if none circled."""
        d = [s.circle_diameter_m for s in self.trials if s.outcome == "circling" and s.circle_diameter_m]
        return _mean(d) if d else None

    @property
    def final_y_m(self) -> list:
        return [s.final_head_xy_m[1] for s in self.trials if s.outcome != "error"]

    @property
    def final_head_xy_m(self) -> list:
        xy = [s.final_head_xy_m for s in self.trials if s.outcome != "error"]
        return np.mean(xy, axis=0).tolist() if xy else [None, None]


def _mean(values) -> float:
    values = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.mean(values)) if values else math.nan


def score_case(*, label, runs) -> CaseScore:
    return CaseScore(label=label, trials=[score_trial(run=r) for r in runs])


def _counts_text(case: CaseScore) -> str:
    n = len(case.trials)
    return ", ".join(f"{name} {k}/{n}" for name, k in case.outcome_counts.items())


def _check(kind, values, case: CaseScore) -> tuple[bool, str]:
    """(holds, what the model did) for one check on a case."""
    every = len(case.trials) > 0
    if kind in ("crossed", "circling"):
        return every and case.count(kind) == len(case.trials), _counts_text(case) + (
            f" ({case.revolutions:.2f} rev)" if kind == "circling" else ""
        )
    if kind == "direction":
        turns = [s.direction or "no turn" for s in case.trials]
        others = ", ".join(f"{d} {turns.count(d)}" for d in sorted(set(turns) - {values[0]}))
        text = f"{values[0]} {turns.count(values[0])}/{len(turns)}" + (f" ({others})" if others else "")
        return every and all(d == values[0] for d in turns), text
    if kind == "diameter":
        d = case.circle_diameter_m
        ok = d is not None and case.count("circling") == len(case.trials)
        return ok and abs(d - values[0]) <= DIAMETER_TOLERANCE * values[0], "no circle" if d is None else f"{d:.2f} m"
    if kind == "final_y":
        y = case.final_y_m
        ok = every and len(y) == len(case.trials) and all(values[0] <= v <= values[1] for v in y)
        text = "no run" if not y else f"y {y[0]:+.2f} m" if len(y) == 1 else f"y {min(y):+.2f} to {max(y):+.2f} m"
        return ok, text
    raise ValueError(f"unknown check '{kind}'")


def _check_across(kind, finding: Finding, cases: dict) -> tuple[bool, str]:
    """Checks that compare cases: the diameters' growth, one case straighter than another."""
    if kind == "diameters_grow":
        d = [cases[c].circle_diameter_m if cases[c].count("circling") == len(cases[c].trials) else None
             for c in finding.cases]  # fmt: skip
        missing = [c for c, v in zip(finding.cases, d, strict=True) if v is None]
        text = f"no circle at {', '.join(missing)}" if missing else ", ".join(f"{v:.2f}" for v in d) + " m"
        return None not in d and all(a < b for a, b in zip(d, d[1:], strict=False)), text
    if kind == "straighter":
        this, other = (_mean([abs(v) for v in cases[c].final_y_m]) for c in finding.cases[:2])
        return this < other, f"|y| {this:.2f} vs {finding.cases[1]} {other:.2f} m"
    raise ValueError(f"unknown check '{kind}'")


@dataclasses.dataclass
class Verdict:
    finding: Finding
    reproduced: bool | None  # None: the paper reports nothing, or the case was not run
    model: str


def judge(*, finding: Finding, cases: dict) -> Verdict:
    """Mark `finding` reproduced or not on `cases` (label -> CaseScore): every check must hold."""
    if any(c not in cases for c in finding.cases):
        return Verdict(finding, None, "not run")
    case = cases[finding.cases[0]]
    if not finding.checks:
        return Verdict(finding, None, _counts_text(case))
    results = [
        _check_across(kind, finding, cases) if kind in ("diameters_grow", "straighter") else _check(kind, v, case)
        for kind, *v in finding.checks
    ]
    return Verdict(finding, all(ok for ok, _ in results), "; ".join(text for _, text in results))


def case_labels(joints=range(1, 14)) -> list:
    """The cases run for `joints`: none, each joint failed in turn, and J7+bias when 7 is among them."""
    return ["none"] + [f"J{j}" for j in joints] + (["J7+bias"] if 7 in joints else [])


def paper_jobs(
    *, joints=range(1, 14), trials=PAPER_TRIALS, friction=None, effects=None, servo=None, time_limit_s=TIME_LIMIT_S
):
    """The sweep jobs of the paper's cases from its start (make_jobs' trial-to-trial jitter), its stop rule; servo:
    the working joints' gains (a config.Servo; default the model's)."""
    from .sweep import make_jobs, single_failure_sets

    common = dict(
        trials=trials,
        friction=friction or Friction(),
        effects=effects,
        servo=servo or Servo(),
        stop=Stop(line_x_m=LINE_X_M, revolutions=CIRCLING_REVOLUTIONS, time_limit_s=time_limit_s),
    )
    jobs = make_jobs(failure_sets=single_failure_sets(joints), **common)
    if 7 in joints:
        biased = make_jobs(failure_sets=[[Failure(joint=7)]], bias_deg=J7_BIAS_DEG, **common)
        jobs += [dataclasses.replace(job, label="J7+bias") for job in biased]
    return jobs


def run_trial(job) -> Trace:
    """Simulate a sweep job in this process and keep what scoring and the figures need; errors become data."""
    from .kinematics import module_positions, module_yaws
    from .sweep import simulate_job

    try:
        run = simulate_job(job)
    except Exception as e:  # noqa: BLE001 - a failed run is data: record it and go on
        message = f"{type(e).__name__}: {' '.join(str(e).split())}"
        empty = np.zeros((0, 2))
        return Trace(np.zeros(0), empty, np.zeros(0), "error", job.label, job.trial, None, message)
    x0 = run.state[0]
    modules = module_positions(complex(x0[0], x0[1]), module_yaws(x0[2], x0[3:16]), run.geometry)
    return Trace(
        t=run.t,
        head_xy=np.array(run.head_xy),
        head_yaw=np.array(run.head_yaw),
        stop_reason=run.stop_reason,
        label=job.label,
        trial=job.trial,
        start_modules_xy=np.column_stack([modules.real, modules.imag]),
    )


def reproduce(
    *,
    friction=None,
    effects=None,
    servo=None,
    joints=range(1, 14),
    trials=PAPER_TRIALS,
    workers=None,
    scheduler=None,
    time_limit_s=TIME_LIMIT_S,
    progress=None,
) -> Reproduction:
    """Run the paper's cases (case_labels(joints)) and score them against FINDINGS; progress(done, total, label)."""
    from .executor import make_executor

    jobs = paper_jobs(
        joints=joints, trials=trials, friction=friction, effects=effects, servo=servo, time_limit_s=time_limit_s
    )
    started = time.perf_counter()
    with make_executor(workers=workers, scheduler=scheduler) as executor:
        futures = {executor.submit(run_trial, job): k for k, job in enumerate(jobs)}
        traces = [None] * len(jobs)
        for done, future in enumerate(as_completed(futures), start=1):
            traces[futures[future]] = future.result()
            if progress:
                progress(done, len(jobs), traces[futures[future]].label)
    settings = {
        "friction": dataclasses.asdict(friction or Friction()),
        "effects": dict(effects or {}),
        "servo": dataclasses.asdict(servo or Servo()),
        "trials": trials,
        "time_limit_s": time_limit_s,
        "j7_bias_deg": J7_BIAS_DEG,
        "wall_s": time.perf_counter() - started,
    }
    return assemble(traces=traces, settings=settings)


def assemble(*, traces, settings=None) -> Reproduction:
    """Score traces (grouped by label, in order) into a Reproduction."""
    by_case: dict = {}
    for trace in traces:
        by_case.setdefault(trace.label, []).append(trace)
    cases = {label: score_case(label=label, runs=runs) for label, runs in by_case.items()}
    verdicts = [judge(finding=f, cases=cases) for f in FINDINGS]
    return Reproduction(cases=cases, verdicts=verdicts, traces=by_case, settings=settings or {})


@dataclasses.dataclass
class Reproduction:
    cases: dict  # label -> CaseScore
    verdicts: list  # Verdict per finding, in FINDINGS' order
    traces: dict  # label -> [Trace], for the figures
    settings: dict

    @property
    def scored(self) -> list:
        return [v for v in self.verdicts if v.reproduced is not None]

    def matches_paper(self, label) -> bool | None:
        """Every scored finding about the case reproduced; None if none is."""
        mine = [v.reproduced for v in self.scored if label in v.finding.cases]
        return all(mine) if mine else None

    def format(self) -> str:
        s = self.settings
        shown = [v for v in self.verdicts if v.model != "not run"]
        head = (
            f"The paper's section 4 against the model: {len(self.cases)} cases, {s.get('trials', '?')} trial(s) each "
            f"from the paper's start; stop at the {LINE_X_M} m line, {CIRCLING_REVOLUTIONS:g} revolutions or "
            f"{s.get('time_limit_s', TIME_LIMIT_S):g} s; J7+bias {J7_BIAS_DEG:+g} deg (paper's B = {PAPER_BIAS:g})"
        )
        head += _servo_text(s.get("servo"))
        rows = [f"{'case':<9}{'paper (where)':<62}{'model':<44}reproduced"]
        for v in shown:
            paper = f"{v.finding.claim} ({v.finding.cite})"
            mark = {True: "yes", False: "NO", None: "n/a"}[v.reproduced]
            rows.append(f"{v.finding.label:<9}{paper:<62}{v.model:<44}{mark}")
        n_yes = sum(bool(v.reproduced) for v in self.scored)
        foot = f"reproduced {n_yes} of {len(self.scored)} findings"
        skipped = len(self.verdicts) - len(shown)
        foot += f"; {skipped} not scored (their cases were not run)" if skipped else ""
        return "\n".join([head, *rows, foot])

    def to_json(self) -> dict:
        cases = {}
        for label, case in self.cases.items():
            cases[label] = {
                "outcome": case.outcome,
                "outcome_counts": case.outcome_counts,
                "direction": case.direction,
                "revolutions": _finite(case.revolutions),
                "circle_diameter_m": case.circle_diameter_m,
                "final_head_xy_m": case.final_head_xy_m,
                "matches_paper": self.matches_paper(label),
                "trials": [
                    {k: _finite(v) for k, v in dataclasses.asdict(t).items()} | {"trial": trace.trial}
                    for t, trace in zip(case.trials, self.traces[label], strict=True)
                ],
            }
        findings = [
            {"cases": list(v.finding.cases), "paper": v.finding.claim, "cite": v.finding.cite}
            | {"model": v.model, "reproduced": v.reproduced}
            for v in self.verdicts
        ]
        return {"settings": self.settings, "findings": findings, "cases": cases}

    def figure(self, *, cases=("none", "J2", "J7", "J13", "J7+bias")):
        """Head paths of `cases` in the style of paper Figs. 8 and 10-13, with the paper's circle and bands."""
        from .plots import findings_figure

        panels = [self._panel(label) for label in cases if label in self.traces]
        return findings_figure(panels, line_x_m=LINE_X_M)

    def _panel(self, label) -> dict:
        """What findings_figure draws for a case: its paths, and the paper's marks from FINDINGS."""
        mine = [f for f in FINDINGS if f.cases[0] == label]
        checks = [c for f in mine for c in f.checks]
        band = next(((f.claim, c[1:]) for f in mine for c in f.checks if c[0] == "final_y"), None)
        diameter = next((c[1] for c in checks if c[0] == "diameter"), None)
        ccw = ("direction", "CCW") in checks
        traces = [t for t in self.traces[label] if t.error is None]
        circle = None
        if diameter is not None and traces:  # through the start, to its left when CCW (Sec. 4: "immediately")
            start = traces[0].head_xy[0]
            circle = (start + np.array([0.0, (0.5 if ccw else -0.5) * diameter]), diameter)
        return {
            "title": f"{label} ({mine[0].cite.removeprefix('Sec. 4, ')})" if mine else label,
            "traces": traces,
            "paper_circle": circle,
            "paper_band_m": band,
        }


def _servo_text(servo) -> str:
    """'; servo KEY=VALUE ...' for the gains that differ from the model's, empty when none does."""
    changed = {k: v for k, v in (servo or {}).items() if v != getattr(Servo(), k)}
    return "; servo " + " ".join(f"{k}={v:g}" for k, v in changed.items()) if changed else ""


def _finite(value):
    return None if isinstance(value, float) and not math.isfinite(value) else value
