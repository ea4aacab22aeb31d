"""Friction found from far: multiple shooting (Bock's method for estimating the parameters of an ODE).

A 10 s replay from a friction far from the data's drifts metres away, and its misfit over the friction is a
landscape of local minima (the crossing's time jumps, a turn comes or goes): a fit from there sees nothing. Cut into
windows of WINDOW_S, each started from what the camera measured there, the same data make a misfit nearly quadratic
in the friction: a window's prediction cannot drift far. So each trial is cut into windows; each window starts from
the head's pose the camera measured at its first sample and the working joints' smoothed angles and rates there (the
data), with the head's three rates and each failed joint's angle and rate (which no sensor reads) as decision
variables; a window's end state and the next window's start differ by continuity defects, penalized in units of
DEFECT_SIGMAS. The friction is shared by every window. Per trial, the start variables are profiled out by
Gauss-Newton at the current friction (their columns exact, from the compiled engine's start-state sensitivities,
engine.session.START_STATE), and the friction's steps (Levenberg-Marquardt over its logarithm, each bounded step a
Drake MathematicalProgram: program._levenberg_marquardt) use the profiled Jacobian: the friction's columns with what
the starts can absorb projected out (variable projection). The full-trial fit refines from its result
(identify_program), where continuity holds exactly.
"""

import dataclasses
import math
import os

import numpy as np

from ..config import RESIDUAL_SIGMAS, Friction, Stop
from ..effects import sensor_model
from ..engine.session import START_RATES
from ..sysid.evaluate import replayer
from ..sysid.parameters import DEFAULT_PARAMETERS
from ..sysid.residual import every_period

WINDOW_S = 2.0  # about three quarters of the gait's period: short enough not to drift, long enough to see friction
# A window's end and the next window's start may differ by about this much (the penalty's units): the head's
# rates (m/s, m/s, rad/s), then each failed joint's angle (rad) and rate (rad/s).
DEFECT_SIGMAS = (0.02, 0.02, 0.1)
FAILED_DEFECT_SIGMAS = (math.radians(2.0), 0.2)
INNER_ITERATIONS = 4  # Gauss-Newton steps on a trial's starts per friction step
# The start variables' box (a failed joint a little past its +-38 deg limit, where a compliant stop lets it go) and
# the largest change of one Gauss-Newton step (a trust region: the misfit is far from quadratic in a start).
START_BOX = (1.0, 1.0, 6.0)  # |vx|, |vy| (m/s), |yaw rate| (rad/s)
FAILED_BOX = (math.radians(43.0), 10.0)  # |angle| (rad), |rate| (rad/s)
START_TRUST = (0.1, 0.1, 0.5)
FAILED_TRUST = (0.2, 1.0)


@dataclasses.dataclass(frozen=True)
class Window:
    """Samples first..last (inclusive) of a trial: it starts from the camera's pose at `first`."""

    first: int
    last: int


def windows(trial, length_s: float = WINDOW_S) -> list[Window]:
    """The trial cut into windows of about `length_s`, each starting at a sample where the camera saw the head (the
    nearest after the nominal boundary) and ending where the next starts; the last ends at the data's end."""
    if trial.camera is None:
        raise ValueError(f"{trial.trial_id}: multiple shooting starts each window from the camera's pose: no camera")
    t = trial.t - trial.t[0]
    seen = ~np.isnan(trial.camera[:, 0])
    starts, nominal = [], 0.0
    while nominal < t[-1] - 0.5 * length_s:
        k = int(np.searchsorted(t, nominal - 1e-9))
        while k < len(t) and not seen[k]:
            k += 1
        if k >= len(t) - 2:
            break
        if not starts or k > starts[-1]:
            starts.append(k)
        nominal += length_s
    ends = starts[1:] + [len(t) - 1]
    return [Window(a, b) for a, b in zip(starts, ends, strict=True)]


def start_names(trial) -> list[str]:
    """A window's start variables: the head's rates, then each failed joint's angle and rate."""
    return [*START_RATES] + [f"start_q{j}_{kind}" for j in trial.failed_joints for kind in ("rad", "rate_rad_s")]


def _state_index(trial) -> list[int]:
    """The plant state's entries of start_names(trial), in order."""
    return [16, 17, 18] + [i for j in trial.failed_joints for i in (2 + j, 18 + j)]


DEFECT_SCALE = [float(os.environ.get("RC1_DEFECT_SCALE", "1"))]


def _defect_sigmas(trial) -> np.ndarray:
    return DEFECT_SCALE[0] * np.array([*DEFECT_SIGMAS, *(FAILED_DEFECT_SIGMAS * len(trial.failed_joints))])


def _per_variable(trial, head, failed) -> np.ndarray:
    return np.array([*head, *(failed * len(trial.failed_joints))])


def bounded_step(trial, starts: np.ndarray, step: np.ndarray) -> np.ndarray:
    """`starts` moved by `step` (windows by variables) scaled down into the trust region, then clipped to the box."""
    trust = _per_variable(trial, START_TRUST, FAILED_TRUST)
    box = _per_variable(trial, START_BOX, FAILED_BOX)
    scale = min(1.0, 1.0 / max(float(np.max(np.abs(step) / trust)), 1e-300))
    return np.clip(starts + scale * step, -box, box)


def first_guess(trial, spans: list[Window]) -> np.ndarray:
    """Each window's start variables as the data suggest them: the head's velocity from the camera's positions a
    period around the start, the IMU's yaw rate, the failed joints at rest at 0 (their angles are not measured)."""
    t = trial.t - trial.t[0]
    out, seen = [], np.flatnonzero(~np.isnan(trial.camera[:, 0]))
    for w in spans:
        near = seen[np.abs(t[seen] - t[w.first]) <= 0.1 + 1e-9]  # about a period's worth of the camera's samples
        velocity = (
            (trial.camera[near[-1], :2] - trial.camera[near[0], :2]) / (t[near[-1]] - t[near[0]])
            if len(near) >= 2
            else np.zeros(2)
        )
        out.append([*velocity, trial.head_yaw_rate[w.first], *([0.0] * 2 * len(trial.failed_joints))])
    return np.array(out)


def _window_run(trial, window: Window, friction: Friction, effects, start: np.ndarray, names):
    """One window's replay from its measured pose and `start`, with sensitivities by `names`."""
    from ..replay import JointReference, replay_initial_state, replay_scenario

    rep = replayer(trial)
    sensors = sensor_model(effects or {})
    full = rep.reference.read_back(sensors)
    t0 = full.t[window.first]
    reference = JointReference(t=full.t[window.first :] - t0, q=full.q[window.first :],
                               q_dot=full.q_dot[window.first :], noise_rad=full.noise_rad)  # fmt: skip
    sliced = dataclasses.replace(
        trial, initial_head_pose=trial.camera[window.first].copy(), initial_head_rates=np.array(start[:3])
    )
    x0 = replay_initial_state(sliced, reference, rep.session.geometry)
    x0[_state_index(trial)[3:]] = start[3:]
    duration = float(trial.t[window.last] - trial.t[window.first])
    scenario = replay_scenario(trial, friction, effects, rep.numerics)
    scenario = dataclasses.replace(scenario, stop=Stop(line_x_m=None, revolutions=None, time_limit_s=duration))
    rep.session.set_joint_reference(reference)
    try:
        return rep.session.simulate(scenario, initial=x0, sensitivities=names)
    finally:
        rep.session.set_joint_reference(rep.reference)


def window_residual(trial, window: Window, run) -> np.ndarray:
    """The camera's head path over the window (every RESIDUAL_PERIOD_S from its first sample, where seen), as the
    camera would report the run, standardized by its sigma."""
    t = trial.t - trial.t[0]
    keep = np.zeros(len(t), dtype=bool)
    keep[every_period(trial)] = True
    keep[window.last] = True
    inside = np.arange(len(t))
    keep &= (inside >= window.first) & (inside <= window.last) & ~np.isnan(trial.camera[:, 0])
    local = t[keep] - t[window.first]
    seen = sensor_model(run.scenario.effects).camera(local, run.t, run.head_xy)
    return ((seen - trial.camera[keep, :2]) / RESIDUAL_SIGMAS["camera_m"]).T.ravel()


def _end_state(run, duration: float) -> tuple:
    """The run's state at `duration` (its last log) and d state / d names there."""
    if abs(run.t[-1] - duration) > 1e-6:
        raise RuntimeError(f"shooting: a window's run ended at {run.t[-1]:.4f} s, not {duration:.4f} s")
    return run.state[-1], run.sensitivity[-1]


def trial_stack(trial, spans, friction: Friction, effects, starts: np.ndarray, free: list[str]) -> tuple:
    """One trial's stacked residuals at `starts` (windows' paths, then the continuity defects), their Jacobian by
    the starts (flattened window by window) and by the `free` friction coefficients."""
    names = start_names(trial)
    n, nw = len(names), len(spans)
    index, sigmas = _state_index(trial), _defect_sigmas(trial)
    paths, path_s, path_f = [], [], []
    defects, defect_s, defect_f = [], [], []
    for w, window in enumerate(spans):
        run = _window_run(trial, window, friction, effects, starts[w], [*names, *free])
        r = window_residual(trial, window, run)
        jac = run.residual_jacobian(lambda moved, window=window: window_residual(trial, window, moved), r)
        block = np.zeros((len(r), n * nw))
        block[:, w * n : (w + 1) * n] = jac[:, :n]
        paths.append(r)
        path_s.append(block)
        path_f.append(jac[:, n:])
        if w + 1 < nw:
            state, sens = _end_state(run, float(trial.t[window.last] - trial.t[window.first]))
            defects.append((state[index] - starts[w + 1]) / sigmas)
            block = np.zeros((n, n * nw))
            block[:, w * n : (w + 1) * n] = sens[:n][:, index].T / sigmas[:, None]
            block[:, (w + 1) * n : (w + 2) * n] = -np.diag(1.0 / sigmas)
            defect_s.append(block)
            defect_f.append(sens[n:][:, index].T / sigmas[:, None])
    r = np.concatenate(paths + defects)
    return r, np.vstack(path_s + defect_s), np.vstack(path_f + defect_f)


def profiled_trial(job) -> tuple:
    """A worker's job: one trial's starts fitted by Gauss-Newton at the friction (step halving where the misfit
    rises), then (residuals, the profiled Jacobian by the free friction, the starts, the window replays run)."""
    trial, friction, effects, starts, free = job
    spans = windows(trial)
    starts = np.array(starts, dtype=float)
    r, js, jf = trial_stack(trial, spans, friction, effects, starts, free)
    stacks = 1
    for _ in range(INNER_ITERATIONS):
        step = np.linalg.lstsq(js, -r, rcond=1e-10)[0].reshape(starts.shape)
        for _ in range(4):
            moved = bounded_step(trial, starts, step)
            r_m, js_m, jf_m = trial_stack(trial, spans, friction, effects, moved, free)
            stacks += 1
            if r_m @ r_m < r @ r:
                break
            step = step / 2
        else:
            break
        gain = (r @ r - r_m @ r_m) / max(r @ r, 1e-300)
        starts, r, js, jf = moved, r_m, js_m, jf_m
        if gain < 1e-3:
            break
    q, _ = np.linalg.qr(js)  # the directions the starts can absorb
    profiled = jf - q @ (q.T @ jf)
    return r, profiled, starts, stacks * len(spans)


@dataclasses.dataclass
class ShootingResult:
    start: Friction
    friction: Friction
    cost_start: float  # 0.5 |r|^2 over the windows' paths and defects, starts profiled out
    cost: float
    iterations: int
    windows: int  # over all trials
    simulations: int  # window replays (each a fraction of a trial's)

    def line(self) -> str:
        moved = ", ".join(
            f"{n} {getattr(self.start, n):.3g} -> {getattr(self.friction, n):.3g}"
            for n in dataclasses.asdict(self.friction)
            if getattr(self.start, n) != getattr(self.friction, n)
        )
        return (
            f"multiple shooting ({self.windows} windows of ~{WINDOW_S:g} s, {self.iterations} iterations, cost "
            f"{self.cost_start:.4g} -> {self.cost:.4g}): {moved or 'nothing moved'}"
        )


def shoot(trials, *, start: Friction, executor, effects=None, parameters=None, max_iterations: int = 12):
    """The free friction coefficients (of `parameters`, DEFAULT_PARAMETERS's by default) that best fit every
    window of `trials` (those with a camera) with their starts profiled out (module docstring), from `start`."""
    from .program import _Coordinates, _levenberg_marquardt

    seen = [t for t in trials if t.camera is not None]
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    if not seen or not free:
        return None
    names = [p.name for p in free]
    coords = _Coordinates.at(free, start, dict(effects or {}))
    starts = [first_guess(t, windows(t)) for t in seen]
    count = {"simulations": 0, "at": None}

    def solve(u):
        friction, model_effects = coords.model(u)
        jobs = [(t, friction, model_effects or effects, s, names) for t, s in zip(seen, starts, strict=True)]
        out = list(executor.map(profiled_trial, jobs)) if executor else [profiled_trial(j) for j in jobs]
        count["simulations"] += sum(o[3] for o in out)
        starts[:] = [o[2] for o in out]  # warm starts for the next friction
        r = np.concatenate([o[0] for o in out])
        jac = np.vstack([o[1] for o in out]) * coords.scale(u)
        count["at"] = (u.copy(), r, jac)
        return r

    def jacobian_at(u, r):
        if count["at"] is None or not np.array_equal(count["at"][0], u):
            solve(u)
        return count["at"][2]

    u0 = np.zeros(len(free))
    r0 = solve(u0)
    lower, upper = coords.bounds()
    u, cost, iterations, _ = _levenberg_marquardt(
        solve, jacobian_at, r0, lower, upper, max_iterations=max_iterations, tolerance=1e-3, on_step=lambda u: None
    )
    return ShootingResult(
        start=start,
        friction=coords.model(u)[0],
        cost_start=0.5 * float(r0 @ r0),
        cost=cost,
        iterations=iterations,
        windows=sum(len(s) for s in starts),
        simulations=count["simulations"],
    )
