"""Equation-error identification: the friction coefficients from inverse dynamics, no simulation.

Where the camera sees the head, a working-joint trial gives the whole configuration at every sample:
the head pose (x, y, yaw) and the 13 potentiometer angles. Smoothing splines (GCV, as in replay.py)
give their first and second derivatives. The plant's equations of motion (paper Eq. 1),

    M(q) q_ddot + C(q, q_dot) = B tau_servo + sum_w J_w^T f_w,

have no servo torque in their first three rows (the head's planar pose is unactuated), and there the
wheel forces of Eqs. 4-5 are linear in the coefficients:

    M_b(q) q_ddot + C_b = sum_w J_long,w^T (-N_w sgn(u_long,w)) mu_long + J_long,w^T (-u_long,w) c_long
                        + sum_w J_lat,w^T  (-N_w sgn(u_lat,w))  mu_lat  + J_lat,w^T  (-u_lat,w)  c_lat

(u: each wheel's rolling and lateral velocity, from the measured q and q_dot; sgn smoothed as in the
model). Stacked over samples this is a linear least-squares problem A theta = b, solved as a Drake
MathematicalProgram with theta >= its lower bounds.

What it cannot see, and why:
- c_joint: it acts only on a failed joint, whose potentiometer is dead, so the configuration of a
  failure trial is not known; failure trials are left out and c_joint is reported not identifiable.
- Wheels that do not slip measurably. The Coulomb term with sgn() smoothed at eps is a damper of rate
  mu N / eps near zero slip (4 N per mm/s); in the paper's gaits the wheels slip sideways at ~0.5 mm/s
  (median), so their lateral forces are constraint forces that no sampled, differentiated velocity can
  attribute to mu_lat. Each sample therefore treats every wheel direction whose measured slip is below
  a gate (5 eps, or 3 times the slip noise) as an unknown force and projects it out of the three base
  rows; a sample with three or more such directions says nothing and is dropped. In the paper's gaits
  that is every sample: equation error then reports all four wheel coefficients not identifiable and
  names a gait whose wheels slip (a standing wave, phase step 0, at 360 deg/s).
- Noise and differentiation bias the fit. The smoothing that makes q_ddot usable also flattens its
  peaks (the left side shrinks: coefficients biased low), and velocity noise enters the regressors
  (errors in variables): the viscous columns are attenuated, and sgn() of a noisy velocity near zero
  is too small, which biases the Coulomb terms of the wheels that barely slip (the lateral ones) high.
  The lateral slip of this nearly kinematic snake is a few mm/s, below what a camera with mm noise
  differentiates, so mu_lat and c_lat are reported with that caveat. The report measures the bias:
  it refits after adding the same noise again (one SIMEX step) and from every other sample (the
  differentiation bias, to first order), and reports both shifts; a coefficient that either moves by
  more than 30% is not identifiable. Measured on the simulator's own states (0.5 ms, consistent
  differences) a standing-wave gait gives mu_lat, c_lat and mu_long within 15%; from 100 Hz samples of
  the same motion, noise-free, stick-slip transitions make the derivatives biased and the fit moves by
  a factor of two, and the camera's 5 mm noise puts the slip noise near 0.1 m/s, above most slips.
- Standard errors come from a sandwich covariance clustered on 1 s blocks: smoothing correlates
  neighbouring residuals, and an ordinary s^2 (A^T A)^-1 would understate them.
"""

import dataclasses
import math
import time

import numpy as np

from ..config import NUM_JOINTS, Z95, Friction, Rc1Error
from ..smoothing import smoothing_spline
from ..sysid.parameters import DEFAULT_PARAMETERS

# The four wheel coefficients the base rows see, in this column order.
WHEEL_NAMES = ("mu_lat", "mu_long", "c_lat", "c_long")
TRIM_S = 0.3  # spline derivatives are poor near a trial's ends and at camera gaps longer than this
BLOCK_S = 1.0  # residual clusters for the sandwich covariance (longer than the smoothing's reach)
YAW_ROW_M = 0.5  # the yaw row (N m) is divided by this length to weigh like the force rows (N)
GATE_EPS = 5.0  # a slip below GATE_EPS * eps is in the smoothed sign's linear range: not attributable
GATE_SIGMAS = 3.0  # ... or below this many standard deviations of its noise
# Makes the model's wheels slip sideways (measured), but needs 188 deg/s of joint speed and more torque than
# RC1's servos give (140 deg/s, 1.19 N m): the robot itself cannot run it.
SLIP_GAIT = (
    "a standing wave (phase_step_deg 0) at 360 deg/s, beyond RC1's servos (188 of 140 deg/s); "
    "within them, fit the friction by simulation (--method program)"
)


@dataclasses.dataclass
class TrajectorySamples:
    """A trial's configuration, velocity and acceleration on the camera's samples."""

    trial_id: str
    t: np.ndarray  # (N,)
    q: np.ndarray  # (N, 16) plant positions [x, y, yaw, q1..q13]
    v: np.ndarray  # (N, 16)
    a: np.ndarray  # (N, 16)


def sees_whole_configuration(trial) -> bool:
    """A trial whose configuration is measured: a camera, and no failed joint (whose angle is not)."""
    return trial.camera is not None and not trial.failed_joints


def _spline_derivatives(t, y, t_eval):
    spline = smoothing_spline(t, y)
    return spline(t_eval), spline.derivative(1)(t_eval), spline.derivative(2)(t_eval)


def trajectory_samples(
    trial, *, trim_s: float = TRIM_S, rng=None, extra_noise=None, every: int = 1
) -> TrajectorySamples | None:
    """Smoothed q, q_dot, q_ddot of a working-joint trial at the camera's samples; None when the trial
    has no camera or a failed joint. `extra_noise` = (camera_m, camera_yaw_rad, potentiometer_rad) adds
    that much noise to the measurements first (for the SIMEX bias estimate); `every` = k keeps every
    k-th sample (for the differentiation bias estimate)."""
    if not sees_whole_configuration(trial):
        return None
    t = (trial.t - trial.t[0])[::every]
    camera = trial.camera[::every].copy()
    joints = trial.q[::every].copy()
    if extra_noise is not None:
        cam_m, cam_yaw, pot = extra_noise
        camera += rng.normal(0.0, 1.0, camera.shape) * np.array([cam_m, cam_m, cam_yaw])
        joints += rng.normal(0.0, pot, joints.shape)
    seen = ~np.isnan(camera[:, 0])
    if seen.sum() < 10:
        return None
    ts = t[seen]
    # Keep samples at least trim_s from either end and from any camera gap longer than trim_s.
    gaps = np.flatnonzero(np.diff(ts) > trim_s)
    edges = np.concatenate([[ts[0]], ts[gaps], ts[gaps + 1], [ts[-1]]])
    near_edge = np.min(np.abs(ts[:, None] - edges[None, :]), axis=1) < trim_s
    keep = ~near_edge
    te = ts[keep]
    if len(te) < 10:
        return None
    n = len(te)
    q, v, a = (np.zeros((n, 3 + NUM_JOINTS)) for _ in range(3))
    yaw = np.unwrap(camera[seen, 2])
    for i, column in enumerate((camera[seen, 0], camera[seen, 1], yaw)):
        q[:, i], v[:, i], a[:, i] = _spline_derivatives(ts, column, te)
    for j in range(NUM_JOINTS):
        q[:, 3 + j], v[:, 3 + j], a[:, 3 + j] = _spline_derivatives(t, joints[:, j], te)
    return TrajectorySamples(trial_id=trial.trial_id, t=te, q=q, v=v, a=a)


def _wheel_toe_only(effects: dict[str, float]) -> float:
    """The wheel toe (rad): the one effect these rows model; any other is refused, not ignored."""
    from ..effects import active, model_setup

    others = [e.name for e in active(effects) if e.name != "wheel_toe"]
    if others:
        raise Rc1Error(f"equation error: effects {', '.join(others)} are not in its rows (only wheel_toe is)")
    return model_setup(effects).wheel_toe_rad


class InverseDynamics:
    """The base rows of the equations of motion, evaluated by the plant, and their friction regressors."""

    def __init__(self, sgn_smoothing_m_s: float = 1e-3, effects: dict[str, float] | None = None):
        from pydrake.systems.framework import DiagramBuilder

        from ..friction import GRAVITY_M_S2
        from ..model import add_rc1_plant

        self.rc1 = add_rc1_plant(DiagramBuilder(), time_step=5e-4)  # the step does not enter M or C
        self.plant = self.rc1.plant
        self.context = self.plant.CreateDefaultContext()
        g = self.rc1.geometry
        self.normal = g.module_mass[g.wheel_module] * GRAVITY_M_S2
        self.eps = sgn_smoothing_m_s
        self.toe = g.arrays[4] * np.exp(1j * _wheel_toe_only(effects or {}))

    def rows(self, samples: TrajectorySamples) -> dict:
        """Per sample k the base rows A[k] theta = b[k] (theta = WHEEL_NAMES; yaw row divided by
        YAW_ROW_M), each wheel's slip u_long, u_lat, and the base-row direction g_long, g_lat along
        which that wheel's force acts (so that an unknown force can be projected out)."""
        from ..friction import smooth_sign
        from ..kinematics import wheel_kinematics_kernel

        jp, jc, module, offset, _ = self.rc1.geometry.arrays
        n, w = len(samples.t), len(self.normal)
        scale = np.array([1.0, 1.0, 1.0 / YAW_ROW_M])
        out = {
            "A": np.zeros((n, 3, len(WHEEL_NAMES))),
            "b": np.zeros((n, 3)),
            "u_long": np.zeros((n, w)),
            "u_lat": np.zeros((n, w)),
            "g_long": np.zeros((n, w, 3)),
            "g_lat": np.zeros((n, w, 3)),
        }
        for k in range(n):
            x = np.concatenate([samples.q[k], samples.v[k]])
            self.plant.SetPositionsAndVelocities(self.context, x)
            M = self.plant.CalcMassMatrix(self.context)
            out["b"][k] = scale * (M[:3] @ samples.a[k] + self.plant.CalcBiasTerm(self.context)[:3])
            _, direction, jacobian = wheel_kinematics_kernel(x, jp, jc, module, offset, self.toe)
            local = np.conj(direction)[:, None] * jacobian
            g_long, g_lat = local.real[:, :3] * scale, local.imag[:, :3] * scale
            u_long, u_lat = local.real @ samples.v[k], local.imag @ samples.v[k]
            out["A"][k] = -np.column_stack(
                [
                    g_lat.T @ (self.normal * smooth_sign(u_lat, self.eps)),
                    g_long.T @ (self.normal * smooth_sign(u_long, self.eps)),
                    g_lat.T @ u_lat,
                    g_long.T @ u_long,
                ]
            )
            out["u_long"][k], out["u_lat"][k], out["g_long"][k], out["g_lat"][k] = u_long, u_lat, g_long, g_lat
        return out


def _projected(rows: dict, gate_long: float, gate_lat: float):
    """Rows with the forces of non-slipping wheel directions projected out: (A, b, sample index)."""
    A_out, b_out, index = [], [], []
    for k in range(len(rows["b"])):
        unknown = np.concatenate(
            [
                rows["g_long"][k][np.abs(rows["u_long"][k]) < gate_long],
                rows["g_lat"][k][np.abs(rows["u_lat"][k]) < gate_lat],
            ]
        )
        if len(unknown) >= 3:
            continue
        if len(unknown):
            _, sv, vt = np.linalg.svd(unknown)
            rank = int((sv > 1e-9 * sv.max()).sum())
            basis = vt[rank:]  # base-row combinations blind to the unknown forces
        else:
            basis = np.eye(3)
        A_out.append(basis @ rows["A"][k])
        b_out.append(basis @ rows["b"][k])
        index += [k] * len(basis)
    if not A_out:
        return np.zeros((0, len(WHEEL_NAMES))), np.zeros(0), np.zeros(0, dtype=int)
    return np.vstack(A_out), np.concatenate(b_out), np.array(index)


def _solve(A, b, lower, upper):
    """min |A theta - b|^2 subject to lower <= theta <= upper, as a MathematicalProgram."""
    from pydrake.solvers import MathematicalProgram, Solve

    prog = MathematicalProgram()
    theta = prog.NewContinuousVariables(A.shape[1], "theta")
    prog.Add2NormSquaredCost(A, b, theta)
    prog.AddBoundingBoxConstraint(lower, upper, theta)
    result = Solve(prog)
    if not result.is_success():
        raise Rc1Error(f"identify: the equation-error least squares failed ({result.get_solution_result()})")
    return result.GetSolution(theta)


@dataclasses.dataclass
class EquationErrorResult:
    friction: Friction  # fitted wheel coefficients; c_joint (and frozen ones) as given at the start
    names: list[str]  # the free wheel coefficients
    standard_errors: list[float]  # inf where the rows do not constrain the coefficient
    correlation: list[list[float]]
    noise_bias: list[float]  # estimate with the noise doubled minus the estimate (one SIMEX step)
    differentiation_bias: list[float]  # estimate from every other sample minus the estimate
    identifiable: list[bool]
    trials_used: list[str]
    trials_skipped: list[str]  # failure trials or trials without a camera
    samples: int  # camera samples of the used trials
    samples_used: int  # samples with at most two non-slipping wheel directions
    slip_gate_m_s: list[float]  # the largest gate (longitudinal, lateral) over the trials
    residual_rms_N: float
    wall_time_s: float
    simulations: int = 0

    def warnings(self) -> list[str]:
        out = [
            "c_joint: not identifiable by equation error (it acts only in a failed joint, whose angle is not "
            "measured); its value is the start value, not a fit"
        ]
        if self.samples_used == 0:
            out.append(
                f"no sample has fewer than three non-slipping wheel directions (slip gate "
                f"{1000 * max(self.slip_gate_m_s):.0f} mm/s): the wheels act as constraints and equation error "
                f"sees no friction coefficient in these trials; a gait whose wheels slip would ({SLIP_GAIT})"
            )
        for n, se, bias, dbias, ok in zip(
            self.names, self.standard_errors, self.noise_bias, self.differentiation_bias, self.identifiable, strict=True
        ):
            if not ok and self.samples_used:
                out.append(
                    f"{n}: not identifiable by equation error from these trials (standard error "
                    f"{_fmt(se)}, noise bias {_fmt(bias)}, differentiation bias {_fmt(dbias)} on "
                    f"{getattr(self.friction, n):.4g}); its value is not a fit"
                )
        return out

    def table(self) -> str:
        lines = [
            f"{'coefficient':<12}{'value':>10}{'std. error':>12}{'95% interval':>24}{'noise bias':>12}"
            f"{'diff. bias':>12}  identifiable"
        ]
        for n, se, bias, dbias, ok in zip(
            self.names, self.standard_errors, self.noise_bias, self.differentiation_bias, self.identifiable, strict=True
        ):
            v = getattr(self.friction, n)
            ci = f"[{v - Z95 * se:.4g}, {v + Z95 * se:.4g}]" if math.isfinite(se) else "-"
            lines.append(
                f"{n:<12}{v:>10.4g}{_fmt(se):>12}{ci:>24}{_fmt(bias):>12}{_fmt(dbias):>12}  {'yes' if ok else 'NO'}"
            )
        lines.append(
            f"{self.samples_used} of {self.samples} samples used, trials {', '.join(self.trials_used) or '-'}"
            f"; skipped (failed joint or no camera): {', '.join(self.trials_skipped) or '-'}"
        )
        return "\n".join(lines)

    def to_json(self) -> dict:
        out = dataclasses.asdict(self)
        out.update(method="equation-error", friction=dataclasses.asdict(self.friction), warnings=self.warnings())
        return {k: _finite_or_none(v) for k, v in out.items()}


def _fmt(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else ("-" if math.isnan(x) else "inf")


def _finite_or_none(value):
    """JSON has no inf or NaN: write null for them, in lists too."""
    if isinstance(value, list):
        return [_finite_or_none(v) for v in value]
    return None if isinstance(value, float) and not math.isfinite(value) else value


def _clustered_fit(A, b, cluster, lower, upper):
    """Bounded least squares and its sandwich covariance, residuals clustered by `cluster`."""
    theta = _solve(A, b, lower, upper)
    r = A @ theta - b
    bread = np.linalg.pinv(A.T @ A)
    meat = np.zeros((A.shape[1], A.shape[1]))
    groups = np.unique(cluster)
    for c in groups:
        s = A[cluster == c].T @ r[cluster == c]
        meat += np.outer(s, s)
    cov = bread @ meat @ bread * len(groups) / max(len(groups) - 1, 1)
    null = np.linalg.matrix_rank(A) < A.shape[1]
    return theta, cov, float(np.sqrt(np.mean(r**2))) if len(r) else math.nan, null


def _blocks(trials, dynamics, cols, fixed, sgn_smoothing_m_s, rng, extra_noise):
    """Each usable trial's rows, three ways (as measured, with the sensors' noise added again, every other sample),
    projected past the slip gate: (passes, trials used, trials skipped, samples, each trial's gate)."""
    passes = ([], [], [])  # (A, b, cluster, samples) blocks: as measured, noise added again, every other sample
    used, skipped, total, gates = [], [], 0, []
    for trial in trials:
        measured = trajectory_samples(trial)
        if measured is None:
            skipped.append(trial.trial_id)
            continue
        noisier = trajectory_samples(trial, rng=rng, extra_noise=extra_noise)
        sparser = trajectory_samples(trial, every=2)
        rows = [dynamics.rows(measured), dynamics.rows(noisier), dynamics.rows(sparser)]
        gate = [
            max(GATE_EPS * sgn_smoothing_m_s, GATE_SIGMAS * float(np.sqrt(np.mean((rows[1][u] - rows[0][u]) ** 2))))
            for u in ("u_long", "u_lat")
        ]
        gates.append(gate)
        for blocks, r, t in zip(passes, rows, (measured.t, noisier.t, sparser.t), strict=True):
            A, b, index = _projected(r, *gate)
            blocks.append(
                (
                    A[:, cols],
                    b - A @ fixed,
                    [f"{trial.trial_id}/{int(t[i] // BLOCK_S)}" for i in index],
                    len(np.unique(index)),
                )
            )
        used.append(trial.trial_id)
        total += len(measured.t)
    return passes, used, skipped, total, gates


def fit_equation_error(
    trials,
    *,
    start: Friction,
    parameters=None,
    sgn_smoothing_m_s: float = 1e-3,
    effects: dict[str, float] | None = None,
    noise=None,
    seed: int = 0,
    max_relative_error: float = 0.3,
) -> EquationErrorResult:
    """Fit the free wheel coefficients of `parameters` from the camera and potentiometer samples of the
    working-joint trials among `trials` (module docstring). `noise` (a synthesize.Noise; default: the
    sensors of data/README.md): its camera and potentiometer deviations are added once more to measure
    the slip noise (for the gate) and the noise bias (SIMEX)."""
    from ..synthesize import Noise

    noise = noise or Noise()
    extra_noise = (noise.camera_m, math.radians(noise.camera_yaw_deg), math.radians(noise.potentiometer_deg))

    began = time.perf_counter()
    parameters = parameters or DEFAULT_PARAMETERS
    free = [p.name for p in parameters if not p.frozen and p.name in WHEEL_NAMES]
    if not free:
        raise Rc1Error("identify: equation error fits only the wheel coefficients, and all of them are frozen")
    cols = [WHEEL_NAMES.index(n) for n in free]
    fixed = np.array([0.0 if n in free else getattr(start, n) for n in WHEEL_NAMES])
    bounds = {p.name: (p.lower, p.upper) for p in parameters}
    lower = np.array([bounds[n][0] for n in free])
    upper = np.array([bounds[n][1] for n in free])
    dynamics = InverseDynamics(sgn_smoothing_m_s, effects)
    passes, used, skipped, total, gates = _blocks(
        trials, dynamics, cols, fixed, sgn_smoothing_m_s, np.random.default_rng(seed), extra_noise
    )
    if not used:
        raise Rc1Error("identify: equation error needs a trial with a camera and no failed joint; none was given")
    fits = []
    for blocks in passes:
        A = np.vstack([blk[0] for blk in blocks])
        b = np.concatenate([blk[1] for blk in blocks])
        cluster = np.array(sum((blk[2] for blk in blocks), []))
        fits.append(_clustered_fit(A, b, cluster, lower, upper) if len(b) >= 2 * len(free) else None)
    if fits[0] is None:
        theta, se, corr, rms = (
            np.array([getattr(start, n) for n in free]),
            np.full(len(free), math.inf),
            np.eye(len(free)),
            math.nan,
        )
        bias = dbias = np.full(len(free), math.nan)
        samples_used = 0
    else:
        theta, cov, rms, null = fits[0]
        se = np.full(len(free), math.inf) if null else np.sqrt(np.clip(np.diag(cov), 0.0, None))
        d = np.where(np.isfinite(se) & (se > 0), se, 1.0)
        corr = np.where(np.isfinite(se)[:, None] & np.isfinite(se)[None, :], cov / np.outer(d, d), 0.0)
        bias, dbias = (fit[0] - theta if fit is not None else np.full(len(free), math.inf) for fit in fits[1:])
        samples_used = sum(blk[3] for blk in passes[0])
    identifiable = [
        bool(max(s, abs(b1), abs(b2)) < max_relative_error * abs(v))
        for v, s, b1, b2 in zip(theta, se, bias, dbias, strict=True)
    ]
    friction = dataclasses.replace(start, **{n: float(v) for n, v in zip(free, theta, strict=True)})
    return EquationErrorResult(
        friction=friction,
        names=free,
        standard_errors=[float(x) for x in se],
        correlation=np.round(corr, 4).tolist(),
        noise_bias=[float(x) for x in bias],
        differentiation_bias=[float(x) for x in dbias],
        identifiable=identifiable,
        trials_used=used,
        trials_skipped=skipped,
        samples=total,
        samples_used=samples_used,
        slip_gate_m_s=np.max(gates, axis=0).tolist(),
        residual_rms_N=rms,
        wall_time_s=time.perf_counter() - began,
    )
