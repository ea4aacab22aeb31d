"""Replay: the model driven by a trial's measured joint angles, as the paper does (section 3).

Working joints follow the measured potentiometer angles kinematically, as the paper drives them; failed
joints are free (their potentiometers are dead). REPLAY_SERVO makes a servo a kinematic joint.

Measured angles are noisy. Each working joint's samples are smoothed by a penalized cubic smoothing
spline whose smoothing weight is chosen by generalized cross-validation (smoothing.py), which also
gives the joint rates; the reference is the C1 cubic Hermite through the smoothed values and rates at
the sample times.
"""

import dataclasses
import functools
import math
import os

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from .config import Failure, Friction, Numerics, Scenario, Servo, Start, Stop
from .effects import sensor_model
from .engine import make_session
from .engine.dynamics import plant_numbers
from .gait import serpenoid, serpenoid_parameters
from .measurements import Trial
from .protocol import Run, rest_state
from .smoothing import smoothed_about_wave
from .start import StartEstimate, fit_start

# The paper's kinematic joints (section 3: a working joint follows the measured motion): a servo whose
# proportional term acts on the reference one step ahead (lead = the time step, set per scenario), stiff
# enough that the implicit step lands each joint on it (tracking converged from Kp 1e7 at 0.5 ms), with no
# torque limit: whatever torque the measured motion took, the servo gave.
REPLAY_SERVO = Servo(kp_Nm_per_rad=1e8, ki_Nm_per_rad_s=0.0, kd_Nm_s_per_rad=0.0, torque_limit_Nm=math.inf)
REPLAY_NUMERICS = Numerics(time_step_s=5e-4)
# A trial stopped by a line or a turn ends its data at the last sample before the event: its replay may run
# this many sample periods past the data (the joints held at their last reference) to reach the event.
EVENT_GRACE_SAMPLES = 3


@dataclasses.dataclass
class JointReference:
    t: np.ndarray  # sample times, from 0, and one knot EVENT_GRACE_SAMPLES past the last
    q: np.ndarray  # (N, 13) smoothed angles (failed joints: 0, unused)
    q_dot: np.ndarray  # (N, 13)
    noise_rad: float  # the potentiometers' noise the smoothing finds (smoothed_samples), pooled over the joints

    def read_back(self, sensors) -> "JointReference":
        """The reference of the angles whose readings these are, read by potentiometers with `sensors`' faults
        (effects.SensorModel: reading = gain * angle + offset): the smoothing is linear and reproduces constants,
        and GCV's choice moves with neither an offset nor a scale, so it is this one mapped back exactly."""
        if sensors.reads_angles:
            return self
        return dataclasses.replace(
            self, q=(self.q - sensors.angle_offsets_rad) / sensors.angle_gains, q_dot=self.q_dot / sensors.angle_gains
        )

    @functools.cached_property
    def trajectory(self):
        """The reference as the Drake engine follows it: the C1 cubic Hermite through (t, q, q_dot)."""
        return PiecewisePolynomial.CubicHermite(self.t, self.q.T, self.q_dot.T)


def joint_reference(trial: Trial, measured_q=None) -> JointReference:
    """The smoothed reference of the trial's working joints (from `measured_q` in place of trial.q, if given)."""
    t = trial.t - trial.t[0]
    measured = trial.q if measured_q is None else measured_q
    q = np.zeros_like(trial.q)
    q_dot = np.zeros_like(trial.q)
    variances = []
    omega = serpenoid_parameters(trial.gait)[1]
    for j in trial.working_joints:  # about the gait's wave: a spline of the angles alone shrinks the wave
        q[:, j - 1], q_dot[:, j - 1], variance = smoothed_about_wave(t, measured[:, j - 1], float(omega[j - 1]))
        variances.append(variance)
    # Past the data (EVENT_GRACE_SAMPLES, to reach a stop event) the joints go on at their last rates; a knot
    # there makes both engines follow the same continuation.
    grace = _grace_s(t)
    t = np.append(t, t[-1] + grace)
    q, q_dot = np.vstack([q, q[-1] + grace * q_dot[-1]]), np.vstack([q_dot, q_dot[-1]])
    return JointReference(t=t, q=q, q_dot=q_dot, noise_rad=float(np.sqrt(np.mean(variances))) if variances else 0.0)


def _grace_s(t) -> float:
    """How long past its data a replay may run to reach its stop event (EVENT_GRACE_SAMPLES periods)."""
    return EVENT_GRACE_SAMPLES * float(np.median(np.diff(t)))


def replay_scenario(trial: Trial, friction: Friction, effects=None, numerics=None) -> Scenario:
    """The scenario of a replay: the trial's failures and stop rule, the given friction (and effects). It runs
    through its stop event to the data's end (Stop.run_through): the final position is the head's at the event
    (or at the end, past the grace, if it never comes), and every measured sample has a replayed state."""
    end, grace = float(trial.t[-1] - trial.t[0]), _grace_s(trial.t)
    if trial.stop.type == "line":
        stop = Stop(line_x_m=trial.stop.value, revolutions=None, time_limit_s=end + grace, run_through=True)
    elif trial.stop.type == "revolutions":
        stop = Stop(line_x_m=None, revolutions=trial.stop.value, time_limit_s=end + grace, run_through=True)
    else:
        stop = Stop(line_x_m=None, revolutions=None, time_limit_s=min(trial.stop.value, end))
    x, y, _ = trial.initial_head_pose
    kwargs = {} if effects is None else {"effects": effects}
    numerics = numerics or REPLAY_NUMERICS
    servo = dataclasses.replace(REPLAY_SERVO, lead_s=numerics.time_step_s)
    return Scenario(
        gait=trial.gait,
        servo=servo,
        friction=friction,
        failures=[Failure(joint=j) for j in trial.failed_joints],
        start=Start(x_m=float(x), y_m=float(y)),
        stop=stop,
        numerics=numerics,
        **kwargs,
    )


def replay_initial_state(trial: Trial, reference: JointReference, geometry) -> np.ndarray:
    """The trial's initial head pose; working joints at their smoothed first sample, failed joints at
    the commanded serpenoid (the start configuration); the head's rates as the trial gives them
    (Trial.initial_head_rates: measured, or set by a fit), else from protocol.rest_state (the synthetic
    campaigns' convention)."""
    q, q_dot = serpenoid(0.0, trial.gait)
    working = [j - 1 for j in trial.working_joints]
    q[working] = reference.q[0, working]
    q_dot[working] = reference.q_dot[0, working]
    x = rest_state(trial.initial_head_pose[:2], float(trial.initial_head_pose[2]), q, q_dot, geometry)
    if trial.initial_head_rates is not None:
        x[16:19] = trial.initial_head_rates
    return x


def with_rest_start(trial: Trial) -> Trial:
    """`trial` with the protocol's head rates at t = 0 (protocol.rest_state) written in, unless it carries its own."""
    if trial.initial_head_rates is not None:
        return trial
    x = replay_initial_state(trial, joint_reference(trial), plant_numbers().geometry)
    return dataclasses.replace(trial, initial_head_rates=x[16:19].copy())


def with_start_guess(trial: Trial) -> Trial:
    """`trial` with a first guess of its head's rates at t = 0 written in, unless it carries its own: vx, vy from
    the protocol (with_rest_start) and the yaw rate the IMU measured at the first sample. The protocol's yaw rate
    comes from the smoothed joint rates at the data's first sample, whose spline end slopes the noise moves by
    tens of deg/s: on four of this model's own trials it missed the truth by 0.07-0.52 rad/s, the IMU by 0.04 at
    most (tests/test_compare.py)."""
    if trial.initial_head_rates is not None:
        return trial
    guess = with_rest_start(trial)
    guess.initial_head_rates[2] = float(trial.head_yaw_rate[0])
    return guess


class Replayer:
    """Replays one trial; keeps its Diagram and Simulator so that refits can re-run it cheaply."""

    def __init__(self, trial: Trial, numerics: Numerics | None = None, *, engine: str | None = None):
        """engine: "drake" or "compiled" (default: engine.default_engine())."""
        self.trial = trial
        self.numerics = numerics or REPLAY_NUMERICS
        self.reference = joint_reference(trial)
        base = replay_scenario(trial, Friction(), numerics=self.numerics)
        self.session = make_session(base, engine=engine, joint_reference=self.reference)
        self.initial = replay_initial_state(trial, self.reference, self.session.geometry)

    def fit_start(self, friction: Friction, effects=None) -> StartEstimate:
        """Replay from the head rates that the trial's first measurements give at this model (start.py) in
        place of the protocol's convention; on the compiled engine (its exact sensitivities), for both."""
        scenario = replay_scenario(self.trial, friction, effects, self.numerics)
        fitter = (
            self.session
            if self.session.engine == "compiled"
            else make_session(scenario, engine="compiled", joint_reference=self.reference)
        )
        estimate = fit_start(self.trial, fitter, scenario, self.initial)
        self.use_start(estimate.head_rates)
        return estimate

    def use_start(self, head_rates) -> None:
        """Replay from these head rates at t = 0 (Trial.initial_head_rates; None: the protocol's convention)."""
        rates = None if head_rates is None else np.array(head_rates, dtype=float)
        self.trial = dataclasses.replace(self.trial, initial_head_rates=rates)
        self.initial = replay_initial_state(self.trial, self.reference, self.session.geometry)

    def run(self, friction: Friction, effects=None, *, sensitivities=()) -> Run:
        """The replay; with `sensitivities` (names, compiled engine) also d state / d parameter (Run.sensitivity)."""
        scenario = replay_scenario(self.trial, friction, effects, self.numerics)
        sensors = sensor_model(effects or {})
        if sensors.reads_angles:
            return self.session.simulate(scenario, initial=self.initial, sensitivities=sensitivities)
        return self._run_following(self.reference.read_back(sensors), scenario, sensitivities)

    def angle_noise_rad(self) -> float:
        """The potentiometers' noise as the smoothing sees it (JointReference.noise_rad)."""
        return self.reference.noise_rad

    def run_resampled(self, friction: Friction, effects, rng) -> Run:
        """A replay from the measured angles with fresh noise of angle_noise_rad() added: how much the
        replay moves with the noise the potentiometers put into its input (a parametric bootstrap)."""
        return self.run_with_angles(friction, effects, self.trial.q + self.angle_noise(rng, self.angle_noise_rad()))

    def angle_noise(self, rng, sigma_rad: float) -> np.ndarray:
        """Gaussian noise of `sigma_rad` on the working joints' samples (zero on the failed joints')."""
        noise = np.zeros_like(self.trial.q)
        working = [j - 1 for j in self.trial.working_joints]
        noise[:, working] = rng.normal(0.0, sigma_rad, (len(noise), len(working)))
        return noise

    def run_with_angles(self, friction: Friction, effects, measured_q: np.ndarray) -> Run:
        """A replay from `measured_q` in place of the trial's angles (same samples), this Diagram reused."""
        reference = joint_reference(self.trial, measured_q).read_back(sensor_model(effects or {}))
        return self._run_following(reference, replay_scenario(self.trial, friction, effects, self.numerics))

    def _run_following(self, reference: JointReference, scenario: Scenario, sensitivities=()) -> Run:
        """The replay with the working joints following `reference` in place of the trial's own, this Diagram reused."""
        self.session.set_joint_reference(reference)
        try:
            initial = replay_initial_state(self.trial, reference, self.session.geometry)
            return self.session.simulate(scenario, initial=initial, sensitivities=sensitivities)
        finally:
            self.session.set_joint_reference(self.reference)


def _with_fitted_start(trial: Trial, friction: Friction, effects) -> Trial:
    if trial.initial_head_rates is not None:
        return trial
    replayer = Replayer(trial)
    replayer.fit_start(friction, effects)
    return replayer.trial


def fit_starts(campaign, *, friction: Friction, effects=None, workers=None, scheduler=None):
    """`campaign` with each trial's head rates at t = 0 fitted to its first 0.5 s at (friction, effects)
    (Replayer.fit_start), where the trial does not give them: a start from the data, held through a fit."""
    from .executor import make_executor

    n = len(campaign.trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, n), scheduler=scheduler) as executor:
        trials = list(executor.map(_with_fitted_start, campaign.trials, [friction] * n, [effects] * n))
    return dataclasses.replace(campaign, trials=trials)


def replay(trial: Trial, friction: Friction, effects=None, numerics=None, *, engine: str | None = None) -> Run:
    return Replayer(trial, numerics, engine=engine).run(friction, effects)


def tracking_rms_deg(run: Run, trial: Trial) -> float:
    """RMS over working joints and samples of (simulated - measured) joint angle, degrees; the simulated angle as the
    potentiometers would read it (effects.SensorModel)."""
    working = [j - 1 for j in trial.working_joints]
    t = trial.t - trial.t[0]
    inside = t <= run.t[-1] + 1e-9
    sensors = sensor_model(run.scenario.effects)
    read = sensors.potentiometers(run.q + sensors.linkage_rad_per_Nm * run.servo_torque)  # the shafts, read
    sim = np.column_stack([np.interp(t[inside], run.t, read[:, j]) for j in working])
    return float(np.degrees(np.sqrt(np.mean((sim - trial.q[inside][:, working]) ** 2))))
