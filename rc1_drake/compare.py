"""Model versus measurements: replay every trial, score it as the paper does (Eq. 6, Table 2), and
measure how well the signals fit over time."""

import contextlib
import dataclasses
import math
import os

import numpy as np

from .config import START_MODES, Friction
from .effects import sensor_model
from .executor import make_executor
from .measurements import Campaign, Trial
from .metrics import circle_diameter, revolutions
from .replay import Replayer, tracking_rms_deg


def simulator_error(predicted_xy, measured_xy, start_xy) -> float:
    """Paper Eq. 6: |predicted - measured head position| / distance travelled * 100 %, where the
    distance travelled is the measured head's displacement from its start."""
    measured = np.asarray(measured_xy, dtype=float)
    travelled = float(np.linalg.norm(measured - np.asarray(start_xy, dtype=float)))
    return 100.0 * float(np.linalg.norm(np.asarray(predicted_xy, dtype=float) - measured)) / travelled


def fit_percent(y, y_hat) -> float:
    """100 (1 - |y - y_hat| / |y - mean(y)|): 100 is a perfect fit, 0 no better than the mean."""
    y, y_hat = np.asarray(y, dtype=float), np.asarray(y_hat, dtype=float)
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / np.linalg.norm(y - y.mean(axis=0))))


@dataclasses.dataclass
class TrialResult:
    trial_id: str
    case: str
    eq6_error_pct: float
    predicted_final_xy_m: list
    measured_final_xy_m: list
    outcome: str  # how the replay ended (replay_outcome)
    yaw_rate_fit_pct: float
    camera_fit_pct: dict | None  # {"x": .., "y": .., "yaw": ..} or None without a camera
    tracking_rms_deg: float
    revolutions_model: float
    revolutions_measured: float
    circle_diameter_model_m: float | None
    circle_diameter_measured_m: float | None
    # Time series for plots and residual analysis (not in the JSON).
    t: np.ndarray = dataclasses.field(repr=False, default=None)
    yaw_rate_residual: np.ndarray = dataclasses.field(repr=False, default=None)
    position_residual: np.ndarray | None = dataclasses.field(repr=False, default=None)

    def to_json(self) -> dict:
        out = {}
        for f in dataclasses.fields(self):
            if f.name in ("t", "yaw_rate_residual", "position_residual"):
                continue
            v = getattr(self, f.name)
            out[f.name] = None if isinstance(v, float) and not math.isfinite(v) else v
        return out


@dataclasses.dataclass
class CampaignReport:
    campaign: str
    friction: Friction
    trials: list[TrialResult]
    runs: dict = dataclasses.field(repr=False, default_factory=dict)  # trial_id -> Run

    def cases(self) -> dict:
        out: dict = {}
        for r in self.trials:
            out.setdefault(r.case, []).append(r)
        return out

    @property
    def mean_eq6_error_pct(self) -> float:
        return float(np.mean([r.eq6_error_pct for r in self.trials]))

    def case_summary(self) -> dict:
        return {
            case: {
                "trials": [r.trial_id for r in rs],
                "eq6_error_pct": [r.eq6_error_pct for r in rs],
                "mean_eq6_error_pct": float(np.mean([r.eq6_error_pct for r in rs])),
                "mean_yaw_rate_fit_pct": float(np.mean([r.yaw_rate_fit_pct for r in rs])),
            }
            for case, rs in self.cases().items()
        }

    def to_json(self) -> dict:
        return {
            "campaign": self.campaign,
            "friction": dataclasses.asdict(self.friction),
            "mean_eq6_error_pct": self.mean_eq6_error_pct,
            "cases": self.case_summary(),
            "trials": [r.to_json() for r in self.trials],
        }

    def table(self) -> str:
        """Paper Table 2: a row per case, a column per trial, and the average."""
        cases = self.cases()
        width = max(len(rs) for rs in cases.values())
        head = f"{'Failure joint':<14}" + "".join(f"{k + 1:>8}" for k in range(width)) + f"{'Avg':>8}"
        lines = [head]
        for case, rs in cases.items():
            cells = "".join(f"{r.eq6_error_pct:7.1f}%" for r in rs) + " " * 8 * (width - len(rs))
            lines.append(f"{case:<14}{cells}{np.mean([r.eq6_error_pct for r in rs]):7.1f}%")
        lines.append(f"{'all trials':<14}" + " " * 8 * width + f"{self.mean_eq6_error_pct:7.1f}%")
        return "\n".join(lines)


def replay_outcome(trial: Trial, run) -> str:
    """How the replay ended: "crossed" or "circling" at the trial's stop event; "data_ended" when its data (and
    their grace) ran out before the replay reached the line or the turns the trial stopped at (a replay short by
    millimetres, the kinematic joints' share of the angle noise: Eq. 6 measures it); "timed_out" at a time stop."""
    if run.stop_reason == "timed_out" and trial.stop.type != "time":
        return "data_ended"
    return run.stop_reason


def score_trial(trial: Trial, run) -> TrialResult:
    """Compare a replay `run` with the trial's measurements."""
    t = trial.t - trial.t[0]
    inside = t <= run.t[-1] + 1e-9
    sensors = sensor_model(run.scenario.effects)  # what the camera and the IMU would report of the run
    rate_sim = sensors.imu(t[inside], run.t, run.head_yaw_rate)
    rate_residual = trial.head_yaw_rate[inside] - rate_sim
    camera_fit, position_residual = None, None
    cam_diameter = None
    if trial.camera is not None:
        seen = inside & ~np.isnan(trial.camera[:, 0])
        sim = sensors.camera(t[seen], run.t, np.column_stack([run.head_xy, np.unwrap(run.head_yaw)]))
        measured = trial.camera[seen].copy()
        measured[:, 2] = np.unwrap(measured[:, 2])
        camera_fit = {name: fit_percent(measured[:, i], sim[:, i]) for i, name in enumerate(("x", "y", "yaw"))}
        position_residual = np.full((len(t), 2), np.nan)
        position_residual[seen] = measured[:, :2] - sim[:, :2]
        position_residual = position_residual[inside]
        if trial.stop.type == "revolutions":
            cam_diameter = circle_diameter(measured[:, :2], measured[:, 2])
    # Revolutions as the robot saw them: its head yaw, integrated from the IMU.
    dt = np.diff(trial.t)
    yaw_measured = np.concatenate([[0.0], np.cumsum(0.5 * (trial.head_yaw_rate[1:] + trial.head_yaw_rate[:-1]) * dt)])
    circling = run.stop_reason == "circling" or trial.stop.type == "revolutions"
    ended = run.until_event()  # the experiment as it ended: its turns and circle up to the stop event
    return TrialResult(
        trial_id=trial.trial_id,
        case=trial.case,
        eq6_error_pct=simulator_error(run.final_head_xy, trial.final_head_xy, trial.initial_head_pose[:2]),
        predicted_final_xy_m=[float(v) for v in run.final_head_xy],
        measured_final_xy_m=[float(v) for v in trial.final_head_xy],
        outcome=replay_outcome(trial, run),
        yaw_rate_fit_pct=fit_percent(trial.head_yaw_rate[inside], rate_sim),
        camera_fit_pct=camera_fit,
        tracking_rms_deg=tracking_rms_deg(run, trial),
        revolutions_model=float(revolutions(ended.head_yaw)),
        revolutions_measured=float(revolutions(yaw_measured)),
        circle_diameter_model_m=float(circle_diameter(ended.head_xy, ended.head_yaw)) if circling else None,
        circle_diameter_measured_m=None
        if cam_diameter is None or not math.isfinite(cam_diameter)
        else float(cam_diameter),
        t=t[inside],
        yaw_rate_residual=rate_residual,
        position_residual=position_residual,
    )


def _replay_and_score(trial: Trial, friction, effects, numerics, start="rest"):
    replayer = Replayer(trial, numerics)
    if start == "fit" and trial.initial_head_rates is None:
        replayer.fit_start(friction, effects)
    run = replayer.run(friction, effects)
    return score_trial(trial, run), run


def compare_campaign(
    campaign: Campaign,
    friction: Friction | None = None,
    effects=None,
    numerics=None,
    workers: int | None = None,
    progress=None,
    start="rest",
) -> CampaignReport:
    """Replay every trial with `friction` (and `effects`) and score it; trials run in parallel on
    `workers` processes (default: every core), each building its own Diagram. start: where the head's rates at
    t = 0 come from, unless the trial gives them: "rest" (the protocol's convention, protocol.rest_state) or "fit"
    (its first 0.5 s, start.py)."""
    if start not in START_MODES:
        raise ValueError(f"start must be one of {START_MODES}, got {start!r}")
    workers = min(workers or os.cpu_count() or 1, len(campaign.trials))
    friction = friction or Friction()
    trials = campaign.trials
    with contextlib.ExitStack() as stack:
        if workers == 1:
            results = (_replay_and_score(t, friction, effects, numerics, start) for t in trials)
        else:
            pool = stack.enter_context(make_executor(workers=workers))
            results = (
                f.result()
                for f in [pool.submit(_replay_and_score, t, friction, effects, numerics, start) for t in trials]
            )
        outputs = []
        for k, (trial, output) in enumerate(zip(trials, results, strict=True)):
            outputs.append(output)
            if progress:
                progress(k + 1, len(trials), trial.trial_id)
    return CampaignReport(
        campaign=str(campaign.path),
        friction=friction,
        trials=[o[0] for o in outputs],
        runs={t.trial_id: o[1] for t, o in zip(trials, outputs, strict=True)},
    )
