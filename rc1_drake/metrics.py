"""Pure functions of runs: the summary of a run, revolutions, circle fits."""

from __future__ import annotations

import dataclasses
import math

import numpy as np


def revolutions(head_yaw) -> float:
    """How many full turns the head's heading made: |yaw(end) - yaw(start)| / 2 pi (yaw unwrapped)."""
    yaw = np.unwrap(np.asarray(head_yaw, dtype=float))
    return abs(yaw[-1] - yaw[0]) / (2 * math.pi)


def fit_circle(xy) -> tuple[np.ndarray, float]:
    """Least-squares circle through points (N, 2) (Kasa's algebraic fit): (centre, radius)."""
    xy = np.asarray(xy, dtype=float)
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    b = (xy**2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(a, b, rcond=None)
    return np.array([cx, cy]), math.sqrt(max(c + cx * cx + cy * cy, 0.0))


def circling_fit(head_xy, head_yaw):
    """(centre, radius) of a circle fitted to the head path over its complete turns; None if < 1 turn."""
    yaw = np.unwrap(np.asarray(head_yaw, dtype=float))
    turned = np.abs(yaw - yaw[0])
    full = math.floor(turned[-1] / (2 * math.pi))
    if full < 1:
        return None
    end = int(np.searchsorted(turned, full * 2 * math.pi)) + 1
    return fit_circle(np.asarray(head_xy)[:end])


def circle_diameter(head_xy, head_yaw) -> float:
    """Mean diameter of the head's circling (nan with less than one complete turn)."""
    fit = circling_fit(head_xy, head_yaw)
    return float("nan") if fit is None else 2 * fit[1]


@dataclasses.dataclass
class Summary:
    outcome: str  # crossed / circling / timed_out
    final_head_xy_m: list
    t_final_s: float
    distance_travelled_m: float  # |final - start| of the head centre (the denominator of Eq. 6)
    lateral_drift_m: float  # final y - start y of the head centre
    revolutions: float
    circle_diameter_m: float | None  # None unless circling
    peak_servo_torque_Nm: float
    wall_time_s: float

    def to_json(self) -> dict:
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in dataclasses.asdict(self).items()
        }


def summarize(run) -> Summary:
    run = run.until_event()  # the experiment as it ended
    xy = run.head_xy
    outcome = run.stop_reason
    return Summary(
        outcome=outcome,
        final_head_xy_m=[float(xy[-1, 0]), float(xy[-1, 1])],
        t_final_s=float(run.t[-1]),
        distance_travelled_m=float(np.linalg.norm(xy[-1] - xy[0])),
        lateral_drift_m=float(xy[-1, 1] - xy[0, 1]),
        revolutions=round(revolutions(run.head_yaw), 4),
        circle_diameter_m=float(circle_diameter(xy, run.head_yaw)) if outcome == "circling" else None,
        peak_servo_torque_Nm=float(np.abs(run.servo_torque).max()),
        wall_time_s=float(run.wall_time_s),
    )
