"""Where the model fails: residual statistics of a compared campaign (issue 6, step "where it fails").

Per trial, from compare.py's replays: how far the head ends from the measurement (Eq. 6), how fast the
camera-path error grows and when it first exceeds 2 cm, whether the yaw-rate residual is white
(lag-1 autocorrelation, Ljung-Box), and how it correlates with features a missing effect would leave
its mark on: the body heading (a tilted floor acts by heading), the wheels' mean lateral slip
(asymmetric or breakaway friction), the gait phase (anything periodic in the undulation), and the failed
joint's angle (dry joint friction). A residual that is white and uncorrelated is noise; structure names
where to look. Trials are listed worst first.
"""

import dataclasses
import math

import numpy as np

from .kinematics import wheel_kinematics
from .measurements import limit_warnings

FEATURES = ("heading_sin", "heading_cos", "lateral_slip", "gait_phase_sin", "gait_phase_cos", "failed_joint_angle")
ERROR_THRESHOLD_M = 0.02


def ljung_box(x, lags: int = 10) -> tuple:
    """Ljung-Box Q over `lags` autocorrelations of x and its p-value under whiteness (chi-squared)."""
    from scipy.stats import chi2

    x = np.asarray(x, dtype=float) - np.mean(x)
    n = len(x)
    denominator = float(x @ x)
    rho = np.array([float(x[k:] @ x[:-k]) / denominator for k in range(1, lags + 1)])
    q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, float(chi2.sf(q, lags))


def lag1(x) -> float:
    x = np.asarray(x, dtype=float) - np.mean(x)
    return float(x[1:] @ x[:-1]) / float(x @ x)


def correlation(y, x) -> tuple:
    """Pearson r of y and x, and its two-sided p-value with the sample size reduced for y's lag-1
    autocorrelation rho (n (1 - rho) / (1 + rho)): neighbouring residuals are not independent."""
    from scipy.stats import t as student

    y, x = np.asarray(y, dtype=float), np.asarray(x, dtype=float)
    if np.std(x) == 0 or np.std(y) == 0:
        return 0.0, 1.0
    r = float(np.corrcoef(y, x)[0, 1])
    rho = max(lag1(y), 0.0)
    n_eff = max(len(y) * (1 - rho) / (1 + rho), 3.0)
    t = r * math.sqrt((n_eff - 2) / max(1 - r * r, 1e-12))
    return r, float(2 * student.sf(abs(t), n_eff - 2))


def trial_features(trial, run, t) -> dict[str, np.ndarray]:
    """The features at the trial's sample times t (s from its start), from its replay `run`."""
    states = np.array([np.interp(t, run.t, run.state[:, i]) for i in range(run.state.shape[1])]).T
    yaws = states[:, 2:3] + np.concatenate([np.zeros((len(t), 1)), np.cumsum(states[:, 3:16], axis=1)], axis=1)
    heading = yaws.mean(axis=1)
    slip = np.empty(len(t))
    for k, x in enumerate(states):
        w = wheel_kinematics(x, run.geometry)
        slip[k] = float(np.mean((np.conj(w.direction) * (w.jacobian @ x[16:])).imag))
    phase = math.radians(trial.gait.frequency_deg_s) * t + math.radians(trial.gait.phase_offset_deg)
    out = {
        "heading_sin": np.sin(heading),
        "heading_cos": np.cos(heading),
        "lateral_slip": slip,
        "gait_phase_sin": np.sin(phase),
        "gait_phase_cos": np.cos(phase),
    }
    if trial.failed_joints:
        out["failed_joint_angle"] = states[:, 3 + trial.failed_joints[0] - 1]
    return out


@dataclasses.dataclass
class TrialResiduals:
    trial_id: str
    case: str
    eq6_error_pct: float
    yaw_rate_residual_rms_rad_s: float
    yaw_rate_lag1: float  # autocorrelation of the yaw-rate residual at one sample
    ljung_box_p: float  # whiteness of the yaw-rate residual (10 lags): small = structure left
    correlations: dict[str, list[float]]  # feature -> [r, p] with the yaw-rate residual
    position_error_rms_m: float | None = None  # camera path, where a camera saw the head
    position_error_growth_m_s: float | None = None  # slope of |position error| against time
    exceeds_2cm_at_s: float | None = None  # when |position error| first exceeds 2 cm


@dataclasses.dataclass
class WhereItFails:
    trials: list[TrialResiduals]  # worst Eq. 6 error first
    cases: dict[str, float]  # case -> mean Eq. 6 error, worst first
    pooled: dict[str, list[float]]  # feature -> [r, p] over every trial's yaw-rate residual
    measurement: list[str] = dataclasses.field(default_factory=list)  # what the data do that the model cannot

    def to_json(self) -> dict:
        return {
            "trials": [dataclasses.asdict(t) for t in self.trials],
            "cases": self.cases,
            "pooled": self.pooled,
            "measurement": self.measurement,
        }

    def table(self) -> str:
        lines = [f"measurement: {m}" for m in self.measurement]
        lines += [
            f"{'trial':<22}{'case':<10}{'Eq.6 %':>8}{'path rms cm':>12}{'grows cm/s':>11}{'>2 cm at s':>11}"
            f"{'LB p':>8}  strongest feature"
        ]

        def cm(v, scale=100):
            return "-" if v is None else f"{scale * v:.1f}"

        for r in self.trials:
            feature, (rr, p) = max(r.correlations.items(), key=lambda kv: abs(kv[1][0]))
            lines.append(
                f"{r.trial_id:<22}{r.case:<10}{r.eq6_error_pct:8.1f}{cm(r.position_error_rms_m):>12}"
                f"{cm(r.position_error_growth_m_s):>11}{cm(r.exceeds_2cm_at_s, 1):>11}{r.ljung_box_p:8.3f}"
                f"  {feature} r={rr:+.2f} (p={p:.2g})"
            )
        return "\n".join(lines)


def where_it_fails(report, campaign) -> WhereItFails:
    """Residual statistics of a compare.CampaignReport (with its runs) of `campaign`."""
    by_id = {t.trial_id: t for t in campaign.trials}
    rows, pooled_y, pooled_x = [], [], {f: [] for f in FEATURES}
    for result in report.trials:
        trial, run = by_id[result.trial_id], report.runs[result.trial_id]
        t, y = result.t, result.yaw_rate_residual
        features = trial_features(trial, run, t)
        pooled_y.append(y - y.mean())
        for f in FEATURES:
            pooled_x[f].append(features[f] - features[f].mean() if f in features else np.full(len(t), np.nan))
        row = TrialResiduals(
            trial_id=result.trial_id,
            case=result.case,
            eq6_error_pct=result.eq6_error_pct,
            yaw_rate_residual_rms_rad_s=float(np.sqrt(np.mean(y**2))),
            yaw_rate_lag1=lag1(y),
            ljung_box_p=ljung_box(y)[1],
            correlations={f: list(correlation(y, x)) for f, x in features.items()},
        )
        if result.position_residual is not None:
            seen = ~np.isnan(result.position_residual[:, 0])
            error = np.linalg.norm(result.position_residual[seen], axis=1)
            row.position_error_rms_m = float(np.sqrt(np.mean(error**2)))
            row.position_error_growth_m_s = float(np.polyfit(t[seen], error, 1)[0])
            over = np.nonzero(error > ERROR_THRESHOLD_M)[0]
            row.exceeds_2cm_at_s = float(t[seen][over[0]]) if len(over) else None
        rows.append(row)
    rows.sort(key=lambda r: -r.eq6_error_pct)
    cases: dict[str, list[float]] = {}
    for r in rows:
        cases.setdefault(r.case, []).append(r.eq6_error_pct)
    y = np.concatenate(pooled_y)
    pooled = {}
    for f in FEATURES:
        x = np.concatenate(pooled_x[f])
        ok = ~np.isnan(x)
        if ok.sum() > 10:
            pooled[f] = list(correlation(y[ok], x[ok]))
    return WhereItFails(
        trials=rows,
        cases=dict(sorted(((c, float(np.mean(v))) for c, v in cases.items()), key=lambda kv: -kv[1])),
        pooled=pooled,
        measurement=limit_warnings([by_id[r.trial_id] for r in report.trials]),
    )
