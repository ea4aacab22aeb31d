"""The replay's start from the data (issue 28): the head's velocity and yaw rate at the first sample.

A trial measures its joints; its body's velocity at the first sample it does not. This project's synthetic
campaigns start with the centre of mass at rest and the mean axis not turning (protocol.rest_state), a
convention no real robot follows: a robot recorded in motion, or one that starts with its head at rest,
replays from that convention with its end off by centimetres (10.7 cm, 3.4% of the distance, in issue 28's
independent model). So the head's three rates at t = 0 are fitted, per trial, to what the trial measured
over its first START_FIT_S: the camera's head path where it saw the head, and the IMU's yaw rate, each
standardized by its channel's sigma (config.RESIDUAL_SIGMAS). The model's own transient from each candidate
start is what is compared, so a start from rest, or in full motion, is found alike. Gauss-Newton with step
halving (a step is taken only where the misfit falls), from the protocol's convention as the first guess; its
Jacobian is the replay's exact sensitivity to the start (engine.session.START_RATES), so the fit runs on the
compiled engine, and both engines replay from its result.
"""

import dataclasses

import numpy as np

from .config import RESIDUAL_SIGMAS, Stop
from .effects import sensor_model

START_FIT_S = 0.5  # the window of measurements that fixes the start
START_ITERATIONS = 6
START_HALVINGS = 4  # a step is halved at most this often before the fit stops where it is
START_TOLERANCE = 1e-6  # m/s and rad/s: the Gauss-Newton step below which the fit has converged
START_NAMES = ("start_head_vx_m_s", "start_head_vy_m_s", "start_head_yaw_rate_rad_s")


@dataclasses.dataclass
class StartEstimate:
    head_rates: np.ndarray  # (3,) vx, vy (m/s), yaw rate (rad/s) of the head at the first sample
    standard_errors: np.ndarray  # (3,) from the fit's Jacobian and its channels' sigmas
    residual_rms: float  # of the standardized residuals at the fit
    samples: int  # measurements used


def start_residual(trial, run, window: float) -> np.ndarray:
    """Standardized misfit of a replay over the trial's first `window` s: camera x, y where seen, IMU yaw rate,
    each as the sensors would report the replay (effects.SensorModel: a late camera, a biased IMU)."""
    t = trial.t - trial.t[0]
    inside = t <= min(window, run.t[-1]) + 1e-9
    sensors = sensor_model(run.scenario.effects)
    parts = [
        (sensors.imu(t[inside], run.t, run.state[:, 18]) - trial.head_yaw_rate[inside])
        / RESIDUAL_SIGMAS["yaw_rate_rad_s"]
    ]
    if trial.camera is not None:
        seen = inside & ~np.isnan(trial.camera[:, 0])
        parts += list(
            (
                (sensors.camera(t[seen], run.t, run.state[:, 0:2]) - trial.camera[seen, :2])
                / RESIDUAL_SIGMAS["camera_m"]
            ).T
        )
    return np.concatenate(parts)


def _residual_and_jacobian(trial, session, scenario, x0, window: float) -> tuple:
    run = session.simulate(scenario, initial=x0, sensitivities=START_NAMES)
    r = start_residual(trial, run, window)
    return r, run.residual_jacobian(lambda moved: start_residual(trial, moved, window), r)


def fit_start(trial, session, scenario, x0, *, window: float = START_FIT_S) -> StartEstimate:
    """The head's rates at t = 0 that make the replay (`session`: a compiled one with the replay's joint reference;
    `scenario`: the replay's) from `x0` (its pose and joint motion; its head rates the first guess) best match
    the trial's first `window` s (module docstring)."""
    x0 = np.array(x0, dtype=float)
    end = min(window, float(trial.t[-1] - trial.t[0]))
    short = dataclasses.replace(scenario, stop=Stop(line_x_m=None, revolutions=None, time_limit_s=end))
    r, jacobian = _residual_and_jacobian(trial, session, short, x0, window)
    for _ in range(START_ITERATIONS):
        step = np.linalg.lstsq(jacobian, -r, rcond=None)[0]
        for _ in range(START_HALVINGS):  # friction's kinks make a full Gauss-Newton step overshoot
            moved = x0.copy()
            moved[16:19] += step
            r_moved, j_moved = _residual_and_jacobian(trial, session, short, moved, window)
            if r_moved @ r_moved < r @ r:
                break
            step = step / 2
        else:
            break  # no step lowers the misfit: here is the fit
        x0, r, jacobian = moved, r_moved, j_moved
        if np.abs(step).max() < START_TOLERANCE:
            break
    errors = np.sqrt(np.diag(np.linalg.pinv(jacobian.T @ jacobian)))
    return StartEstimate(
        head_rates=x0[16:19].copy(), standard_errors=errors, residual_rms=float(np.sqrt(np.mean(r**2))), samples=len(r)
    )
