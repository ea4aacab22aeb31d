"""Compensating a failed joint (paper sections 4-5): a chosen bias, a heading controller that sets the
bias during the run, and reverse driving for failures near the head.

- `auto_bias`: the uniform bias B (Eq. 7, every joint) that minimizes the head's lateral drift at the
  end of the run, by a bounded scalar search (the paper picked B = 3.0 by hand and calls a method
  future work).
- `with_heading_control`: the closed-loop bias of config.HeadingControl.
- `reversed_drive`: the wave runs tail to head (phase step negated) and the body starts turned by
  180 deg, so the snake moves tail first and a failure near the head is near the rear.
"""

import dataclasses

from scipy.optimize import minimize_scalar

from .config import Gait, HeadingControl, Scenario, Start
from .engine import make_session

FEEDBACK = HeadingControl(kp=0.2, ki_per_s=0.1)


def lateral_drift(run) -> float:
    return float(run.head_xy[-1, 1] - run.head_xy[0, 1])


def with_bias(scenario: Scenario, bias_deg: float) -> Scenario:
    return dataclasses.replace(scenario, gait=dataclasses.replace(scenario.gait, bias_deg=bias_deg))


def with_heading_control(scenario: Scenario, control: HeadingControl = FEEDBACK) -> Scenario:
    heading = scenario.start.heading_deg
    return dataclasses.replace(scenario, heading_control=dataclasses.replace(control, heading_ref_deg=heading))


def reversed_drive(scenario: Scenario) -> Scenario:
    gait: Gait = scenario.gait
    start: Start = scenario.start
    return dataclasses.replace(
        scenario,
        gait=dataclasses.replace(gait, phase_step_deg=-gait.phase_step_deg),
        start=dataclasses.replace(start, heading_deg=start.heading_deg + 180.0),
    )


@dataclasses.dataclass
class BiasSearch:
    bias_deg: float
    drift_m: float
    runs: int
    history: list  # (bias_deg, drift_m) of every run


def auto_bias(
    scenario: Scenario, *, bounds_deg=(-3.0, 3.0), tolerance_deg=0.05, max_runs=16, session=None
) -> BiasSearch:
    """The uniform bias in `bounds_deg` that minimizes |lateral drift| at the end of the run."""
    session = session or make_session(scenario)
    history = []

    def drift(bias_deg):
        run = session.simulate(with_bias(scenario, float(bias_deg)))
        history.append((float(bias_deg), lateral_drift(run)))
        return abs(history[-1][1])

    minimize_scalar(drift, bounds=bounds_deg, method="bounded", options={"xatol": tolerance_deg, "maxiter": max_runs})
    best = min(history, key=lambda h: abs(h[1]))
    return BiasSearch(bias_deg=best[0], drift_m=best[1], runs=len(history), history=history)


def compensation_study(scenario: Scenario) -> dict:
    """Each compensation on one failure scenario: drift, progress and outcome, in one worker."""
    from .metrics import summarize

    def describe(run, **extra):
        s = summarize(run)
        return {
            "outcome": s.outcome,
            "lateral_drift_m": s.lateral_drift_m,
            "progress_x_m": float(run.head_xy[-1, 0] - run.head_xy[0, 0]),
            "t_final_s": s.t_final_s,
            **extra,
        }

    session = make_session(scenario)
    out = {"none": describe(session.simulate(scenario))}
    search = auto_bias(scenario, session=session)
    out["bias"] = describe(
        session.simulate(with_bias(scenario, search.bias_deg)), bias_deg=search.bias_deg, search_runs=search.runs
    )
    out["feedback"] = describe(make_session(with_heading_control(scenario)).simulate(with_heading_control(scenario)))
    reverse = reversed_drive(scenario)
    reverse_session = make_session(reverse)
    out["reverse"] = describe(reverse_session.simulate(reverse))
    rsearch = auto_bias(reverse, session=reverse_session)
    out["reverse+bias"] = describe(
        reverse_session.simulate(with_bias(reverse, rsearch.bias_deg)),
        bias_deg=rsearch.bias_deg,
        search_runs=rsearch.runs,
    )
    return out
