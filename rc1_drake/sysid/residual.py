"""The standardized residual of one replay against its trial: the final head position and the camera path
(or the yaw rate, without a camera), each divided by its channel's stated noise (config.RESIDUAL_SIGMAS), so
that its Jacobian gives a Fisher information.
"""

import numpy as np

from ..config import RESIDUAL_SIGMAS, Friction
from ..effects import sensor_model
from ..engine import default_engine
from ..engine.session import sensitivity_parameters
from .evaluate import replay, replayer

RESIDUAL_PERIOD_S = 0.1  # s between a path's residuals, whatever the sampling rate
FINAL_CHANNEL, PATH_CHANNEL = 0, 1  # the final position (by hand); the camera path or yaw rate over time
ANGLE_CHANNEL = 2  # the working joints' angles against the model's servos (angle_residual)
# The least potentiometer noise an angle residual is standardized by (a noise-free trial's smoothing finds none).
ANGLE_NOISE_FLOOR_RAD = 1e-4


def trial_residual(trial, run) -> np.ndarray:
    """Standardized residuals of one replay: the final head position (the head's at the replay's stop event,
    Run.final_head_xy) and, every RESIDUAL_PERIOD_S of the trial's samples up to the replay's time limit, the
    head's x and y where the camera saw it, or its yaw rate when the trial has no camera. The entries, and their
    times, are the trial's whatever the model: a replay runs through its stop event (Stop.run_through), so a
    parameter that moves the crossing moves the residuals, not their number (a Jacobian's columns line up).

    Why not both: the replayed yaw rate differs from a noise-free truth's by ~0.05 rad/s RMS whatever
    the friction (the smoothed potentiometer noise shakes the head), so with a camera that channel adds
    systematic error that biases the fit more than it informs it; the camera's positions match to ~2 mm at the
    true coefficients (measured on a 3 s joint-7 trial)."""
    t = trial.t - trial.t[0]
    keep = np.zeros(len(t), dtype=bool)
    keep[every_period(trial)] = True
    keep &= t <= run.scenario.stop.time_limit_s + 1e-9
    if run.t[-1] < t[keep][-1] - 1e-9:
        raise ValueError(
            f"{trial.trial_id}: the replay ended at {run.t[-1]:.3f} s, before the sample at {t[keep][-1]:.3f} s "
            "(a replay runs through its stop event: Stop.run_through)"
        )
    final = run.final_head_xy
    parts = [(final - trial.final_head_xy) / RESIDUAL_SIGMAS["final_m"]]
    sensors = sensor_model(run.scenario.effects)  # what the camera and the IMU would report of the run
    if trial.camera is not None:
        seen = keep & ~np.isnan(trial.camera[:, 0])
        parts += list(
            ((sensors.camera(t[seen], run.t, run.head_xy) - trial.camera[seen, :2]) / RESIDUAL_SIGMAS["camera_m"]).T
        )
    else:
        parts.append(
            (sensors.imu(t[keep], run.t, run.head_yaw_rate) - trial.head_yaw_rate[keep])
            / RESIDUAL_SIGMAS["yaw_rate_rad_s"]
        )
    return np.concatenate(parts)


def residual_channels(residual, angles: int = 0) -> np.ndarray:
    """Which channel each of one trial's residuals (trial_residual, then `angles` rows of angle_residual) belongs
    to: its first two are the final position, then the camera path or the yaw rate, then the angles."""
    path = len(residual) - 2 - angles
    return np.r_[FINAL_CHANNEL, FINAL_CHANNEL, np.full(path, PATH_CHANNEL), np.full(angles, ANGLE_CHANNEL)]


def angle_residual(trial, twin) -> np.ndarray:
    """The working joints' angles of `twin` — the trial as the model's servos make it from its command
    (synthesize.noise_free_twin, read by the model's potentiometers) — against the trial's measured angles, every
    RESIDUAL_PERIOD_S, joint after joint, standardized by the potentiometers' noise as the trial's smoothing
    estimates it. A servo's tracking error is its load: a force the kinematic replay cannot see (it follows the
    measured angles, whatever torque that takes) moves the angles the servos reach (docs/findings.md)."""
    every, working = every_period(trial), [j - 1 for j in trial.working_joints]
    sigma = max(replayer(trial).angle_noise_rad(), ANGLE_NOISE_FLOOR_RAD)
    return ((twin.q[every, working] - trial.q[every, working]) / sigma).T.ravel()


def angle_rows(trial) -> int:
    """How many rows angle_residual gives for `trial`."""
    return len(trial.t[every_period(trial)]) * len(trial.working_joints)


def every_period(trial) -> slice:
    """The trial's samples every RESIDUAL_PERIOD_S (the nearest whole number of sample periods), from the first."""
    return slice(None, None, max(1, int(round(RESIDUAL_PERIOD_S / (trial.t[1] - trial.t[0])))))


def residual_jacobian(trial, run, residual) -> np.ndarray:
    """d trial_residual / d parameter (one column per run.sensitivity_names) of a run with sensitivities: exact,
    the residuals being linear in the logged states (Run.residual_jacobian)."""
    return run.residual_jacobian(lambda moved: trial_residual(trial, moved), residual)


def replay_residual(trial, friction: Friction, effects=None) -> np.ndarray:
    return trial_residual(trial, replay(trial, friction, effects))


def replay_residual_and_jacobian(trial, friction: Friction, effects, names) -> tuple:
    """One trial's residuals and their derivatives by the parameters `names` from one replay with exact
    sensitivities (engine/tangent.py)."""
    run = replayer(trial).run(friction, effects, sensitivities=names)
    r = trial_residual(trial, run)
    return r, residual_jacobian(trial, run, r)


def exact_jacobian_available(names) -> bool:
    """Whether replays can give the residuals' derivatives by `names` exactly (the compiled engine's
    sensitivities), in place of finite-difference columns."""
    return default_engine() == "compiled" and all(n in sensitivity_parameters() for n in names)
