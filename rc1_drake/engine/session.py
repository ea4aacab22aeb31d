"""CompiledSession: protocol.Session's interface (`simulate(scenario, initial=None) -> Run`) on the
compiled engine. It takes the same Scenario, reads the robot from the same MultibodyPlant, and returns
the same Run; only the arithmetic runs in one compiled call instead of the Simulator's loop.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

import numpy as np

from ..config import FRICTION_NAMES, NUM_JOINTS, Rc1Error, Scenario
from ..diagram import build_key
from ..effects import (
    LIBRARY,
    commanded_gait,
    coordinate_owner,
    effect_values,
    model_setup,
    running_servo,
    shifted,
    stop_backstops,
)
from ..friction import FAILED, FREE, LOCKED, friction_parameters
from ..gait import serpenoid_parameters
from ..model import with_backstops
from ..protocol import Run, Session, initial_state
from .dynamics import plant_numbers
from .run import CIRCLING, CROSSED, NOT_FINITE, REFERENCE, SERPENOID, advance_run

_REASON = {CROSSED: "crossed", CIRCLING: "circling"}
_EVENT_COORDINATE = {CROSSED: 0, CIRCLING: 2}  # the stop rule's state: the head's x, its yaw
_WARNED = set()


def _updates_before(t: float, dt: float) -> int:
    """How many updates (at the floating-point times k * dt, as the Simulator schedules them) come before t:
    the index of the state at time t."""
    k = max(int(math.ceil(t / dt)), 0)
    while k > 0 and (k - 1) * dt >= t:
        k -= 1
    while k * dt < t:
        k += 1
    return k


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"rc1: note: {message}", file=sys.stderr)


@dataclasses.dataclass(frozen=True)
class HermiteReference:
    """A C1 cubic joint reference as its knots: what PiecewisePolynomial.CubicHermite(t, q.T, q_dot.T) holds."""

    t: np.ndarray  # (N,) s
    q: np.ndarray  # (N, 13) rad
    q_dot: np.ndarray  # (N, 13) rad/s

    @classmethod
    def from_trajectory(cls, trajectory) -> HermiteReference:
        """The knots of a Drake PiecewisePolynomial of cubic (or lower) segments that is C1 at its breaks."""
        if trajectory.getSegmentPolynomialDegree(0) > 3:
            raise ValueError("the compiled engine follows C1 cubic joint references (PiecewisePolynomial.CubicHermite)")
        t = np.array(trajectory.get_segment_times())
        derivative = trajectory.derivative(1)
        return cls(
            t=t,
            q=np.array([trajectory.value(s).ravel() for s in t]),
            q_dot=np.array([derivative.value(s).ravel() for s in t]),
        )


class CompiledSession:
    """Runs scenarios on the compiled engine (engine/step.py, engine/run.py); see protocol.Session."""

    engine = "compiled"

    def __init__(self, scenario: Scenario | None = None, *, joint_reference=None):
        self.numbers = plant_numbers()
        self._drake = None  # the fallback for effects with a Python force
        self.set_joint_reference(joint_reference)

    @property
    def geometry(self):
        return self.numbers.geometry

    def set_joint_reference(self, joint_reference) -> None:
        """Follow `joint_reference` (replay.JointReference, HermiteReference or a cubic Drake
        PiecewisePolynomial) from the next run; None: the gait."""
        if joint_reference is None or isinstance(joint_reference, HermiteReference):
            self.joint_reference = joint_reference
        elif hasattr(joint_reference, "q_dot"):
            self.joint_reference = HermiteReference(
                t=np.asarray(joint_reference.t, dtype=float),
                q=np.asarray(joint_reference.q, dtype=float),
                q_dot=np.asarray(joint_reference.q_dot, dtype=float),
            )
        else:
            self.joint_reference = HermiteReference.from_trajectory(joint_reference)
        if self._drake is not None:
            self._drake.set_joint_reference(self._trajectory())

    def _trajectory(self):
        from pydrake.trajectories import PiecewisePolynomial

        ref = self.joint_reference
        return None if ref is None else PiecewisePolynomial.CubicHermite(ref.t, ref.q.T, ref.q_dot.T)

    def _on_drake(self, scenario: Scenario, initial) -> Run:
        """Runs whose effects carry a Python force (ModelSetup.extra_forces) go to the Drake engine."""
        _warn_once(
            "an effect adds a Python force (ModelSetup.extra_forces), which the compiled engine cannot "
            "call: such runs use the Drake engine"
        )
        drake = self._drake
        if drake is None or build_key(scenario, drake.joint_reference) != drake.built.build_key:
            self._drake = Session(scenario, joint_reference=self._trajectory())
        return self._drake.simulate(scenario, initial=initial)

    def simulate(self, scenario: Scenario, *, initial=None, sensitivities=()) -> Run:
        """Run `scenario` (from `initial`, a plant state, if given), as protocol.Session.simulate does; with
        `sensitivities` (names of sensitivity_parameters()) the Run also carries d state / d parameter."""
        setup = model_setup(scenario.effects)
        if setup.extra_forces:
            if sensitivities:
                raise Rc1Error("sensitivities need the compiled engine, which cannot run a Python force")
            return self._on_drake(scenario, initial)
        if sensitivities and setup.tail_tether_N:
            raise Rc1Error("sensitivities: the tangent model does not carry the tail tether (effects.TailTether)")
        x = np.array(initial_state(scenario, self.geometry) if initial is None else initial, dtype=float)
        if x.shape != (32,):
            raise ValueError(f"initial state must have 32 entries, got shape {x.shape}")
        run = _CompiledRun(self, scenario, setup, x, tuple(sensitivities))
        dt, t_end = scenario.numerics.time_step_s, scenario.stop.time_limit_s
        run.advance(0, 0)  # no update: numba compiles or loads the kernels here, outside the run's wall time
        start = time.perf_counter()
        status, k = 0, 0
        for failure in sorted((f for f in scenario.failures if 0.0 < f.time_s < t_end), key=lambda f: f.time_s):
            status, k = run.advance_to(_updates_before(failure.time_s, dt), k)  # as Session: to the failure, on
            if status:
                break
            if run.log_due(k, failure.time_s):
                run.probe(k, failure.time_s, logs=True)  # a log at t_f itself is published by AdvanceTo(t_f): before
            self._fail(failure, run.params, run.power, run.locked, run.x)
        if not status:
            status, k = run.advance_to(_updates_before(t_end, dt), k)
        wall = time.perf_counter() - start
        if status == NOT_FINITE:
            raise Rc1Error(f"simulation failed at t = {k * dt:.3f} s: the state is not finite")
        t_stop = k * dt if status else t_end
        if run.event is not None:
            status = run.event[0]
        t, state, torque, sensitivity = run.logs()
        if len(t) == 0 or t[-1] < t_stop - 1e-12:  # close the logs at the exact stop time, as the Drake engine does
            t = np.append(t, t_stop)
            state = np.vstack([state, run.x])
            torque = np.vstack([torque, run.probe(k, t_stop, logs=False)])
            sensitivity = np.concatenate([sensitivity, run.sens[None]])
        if run.names and status in _EVENT_COORDINATE and run.event is None:
            sensitivity[-1] = run.at_event(k, t_stop, sensitivity[-1], _EVENT_COORDINATE[status])
        _, event_t, event_state, event_sensitivity = run.event or (None, None, None, None)
        return Run(
            scenario=scenario,
            t=t,
            state=state,
            servo_torque=torque,
            stop_reason=_REASON.get(status, "timed_out"),
            wall_time_s=wall,
            geometry=self.geometry,
            sensitivity=sensitivity if run.names else None,
            sensitivity_names=run.names,
            event_t=event_t,
            event_state=event_state,
            event_sensitivity=event_sensitivity if run.names else None,
        )

    def _fail(self, failure, params, power, locked, x) -> None:
        """servo.FailureSwitch.fail on the compiled engine's arrays."""
        j = failure.joint - 1
        if failure.mode == "weak":
            power[j] = min(failure.weak_torque_Nm, self.numbers.effort_limit[j])
            return
        power[j] = 0.0
        params[FAILED][j] = LOCKED if failure.mode == "locked" else FREE
        if failure.mode == "locked":
            locked[j], x[19 + j] = True, 0.0

    def _source(self, scenario: Scenario):
        """(source kind, serpenoid (4, 13), heading controller row, reference knots) of a run."""
        if self.joint_reference is not None:
            ref = self.joint_reference
            return (
                REFERENCE,
                np.zeros((4, NUM_JOINTS)),
                np.zeros(5 + 16),
                (
                    np.ascontiguousarray(ref.t, dtype=float),
                    np.ascontiguousarray(ref.q, dtype=float),
                    np.ascontiguousarray(ref.q_dot, dtype=float),
                ),
            )
        amp, omega, phase, bias = serpenoid_parameters(commanded_gait(scenario.gait, scenario.effects))
        hc = scenario.heading_control
        heading = np.zeros(5 + 16)
        if hc.active:
            heading[:5] = [1.0, hc.kp, hc.ki_per_s, math.radians(hc.bias_limit_deg), math.radians(hc.heading_ref_deg)]
            heading[5 + 2] = 1.0  # mean module yaw = head yaw + sum_i (14 - i)/14 q_i (diagram.add_heading_control)
            heading[5 + 3 :] = (NUM_JOINTS + 1 - np.arange(1, NUM_JOINTS + 1)) / (NUM_JOINTS + 1)
        empty = (np.zeros(2), np.zeros((2, NUM_JOINTS)), np.zeros((2, NUM_JOINTS)))
        return SERPENOID, np.array([amp, omega, phase, bias]), heading, empty


class _CompiledRun:
    """One run's arrays for run.advance_run: the carried state (changed in place), the logs, the constants."""

    def __init__(self, session: CompiledSession, scenario: Scenario, setup, x, names=()):
        numbers = session.numbers
        self.dt = scenario.numerics.time_step_s
        self.params = friction_parameters(
            friction=scenario.friction,
            sgn_smoothing_m_s=scenario.numerics.sgn_smoothing_m_s,
            setup=setup,
            geometry=numbers.geometry,
        )
        limit = scenario.servo.torque_limit_Nm
        self.power = numbers.effort_limit.copy() if limit is None else np.full(NUM_JOINTS, float(limit))
        self.locked = np.zeros(NUM_JOINTS, dtype=np.bool_)
        self.x = x
        for failure in scenario.failures:
            if failure.time_s == 0.0:  # as configure_context: the switch acts on the start state
                session._fail(failure, self.params, self.power, self.locked, self.x)
        self.z, self.z_heading, self.segment = np.zeros(NUM_JOINTS), np.zeros(1), np.zeros(1, dtype=np.int64)
        self.log_next, self.last_torque = np.zeros(1, dtype=np.int64), np.zeros(NUM_JOINTS)
        self.log_t, self.log_steps = _log_schedule(scenario.numerics.log_period_s, scenario.stop.time_limit_s, self.dt)
        self.names = names
        self.run_through, self.event = scenario.stop.run_through, None
        self.dparams, self.dgravity, seeds = sensitivity_directions(scenario, names, len(self.params))
        self.sens, self.sens_z, self.sens_zh = seeds, np.zeros((len(names), NUM_JOINTS)), np.zeros(len(names))
        self.log_sens = np.zeros((len(self.log_steps), len(names), 32))
        self.log_state = np.zeros((len(self.log_steps), 32))
        self.log_torque = np.zeros((len(self.log_steps), NUM_JOINTS))
        source, gait, heading, knots = session._source(scenario)
        stop = scenario.stop
        self.stop_row = stop_row = np.array(
            [
                np.nan if stop.line_x_m is None else stop.line_x_m,
                np.inf if stop.revolutions is None else 2 * math.pi * stop.revolutions,
                x[2],
            ]
        )
        gravity = setup.gravity
        model = np.array([gravity[0], gravity[1], float(bool(gravity[0] or gravity[1]))])
        s = running_servo(scenario.servo, scenario.effects)
        gains = np.array([s.kp_Nm_per_rad, s.ki_Nm_per_rad_s, s.kd_Nm_s_per_rad, s.lead_s])
        self.constant = (
            self.log_state,
            self.log_torque,
            source,
            gait,
            heading,
            *knots,
            gains,
            stop_row,
            model,
            numbers.masses(setup.payload_module, setup.payload_kg),
            numbers.central_yaw_inertia,
            numbers.com,
            *with_backstops(
                numbers.lower_limit, numbers.upper_limit, stop_backstops(scenario.effects, scenario.failures)
            ),
            numbers.geometry.arrays,
        )

    def advance_to(self, k1: int, k0: int) -> tuple:
        """Updates k0 <= k < k1 (advance); through a stop event when the scenario runs through them (Stop.run_through):
        the event's (status, time, state, sensitivities) kept in self.event, its rules then switched off."""
        status, k = self.advance(k0, k1)
        if status in _EVENT_COORDINATE and self.run_through:
            t = k * self.dt
            sens = self.at_event(k, t, self.sens.copy(), _EVENT_COORDINATE[status]) if self.names else None
            self.event = (status, t, self.x.copy(), sens)
            self.stop_row[:2] = np.nan, np.inf  # in the kernel's constants: no rule fires again
            status, k = self.advance(k, k1)
        return status, k

    def advance(self, k0: int, k1: int, t_first: float = np.nan, *, carried=None) -> tuple:
        """Updates k0 <= k < k1 (run.advance_run) on the carried state, or on `carried` (a copy) if given."""
        x, z, zh, seg, params, power, locked, log_next, last, sens, sens_z, sens_zh = carried or self._carried()
        return advance_run(
            x,
            z,
            zh,
            seg,
            k0,
            k1,
            t_first,
            self.dt,
            np.zeros(16),
            params,
            power,
            locked,
            self.log_steps,
            self.log_t,
            log_next,
            last,
            *self.constant,
            sens,
            sens_z,
            sens_zh,
            self.dparams,
            self.dgravity,
            self.log_sens,
        )

    def _carried(self) -> list:
        return [
            self.x,
            self.z,
            self.z_heading,
            self.segment,
            self.params,
            self.power,
            self.locked,
            self.log_next,
            self.last_torque,
            self.sens,
            self.sens_z,
            self.sens_zh,
        ]

    def log_due(self, k: int, t: float) -> bool:
        due = self.log_next[0]
        return due < len(self.log_steps) and self.log_steps[due] == k and self.log_t[due] <= t

    def probe(self, k: int, t: float, *, logs: bool) -> np.ndarray:
        """The step at k, at time t, without taking it: its servo torque; it writes the logs due then if `logs`."""
        copy = [np.array(c, copy=True) for c in self._carried()]
        if not logs:
            copy[7][0] = len(self.log_steps)
        self.advance(k, k + 1, t, carried=copy)
        if logs:
            self.log_next[0] = copy[7][0]
        return copy[8]

    def at_event(self, k: int, t: float, sens, coordinate: int):
        """The sensitivities `sens` (P, 32) at the step k that ended the run by a stop rule (x[coordinate]
        reaching its threshold), turned into those of the state at the event itself, so that they follow the
        stop time as it moves with a parameter: S(t*) - xdot S_c(t*) / xdot_c, with S(t*) taken back from the
        step's end to the crossing along dS/dt and xdot, dS/dt from a probe of the next step."""
        carried = [np.array(c, copy=True) for c in self._carried()]
        carried[7][0] = len(self.log_steps)
        self.advance(k, k + 1, t, carried=carried)
        x_dot = np.concatenate([self.x[16:], (carried[0][16:] - self.x[16:]) / self.dt])
        if coordinate == 0:
            past = self.x[0] - self.stop_row[0]
        else:
            turned = self.x[2] - self.stop_row[2]
            past = turned - math.copysign(self.stop_row[1], turned)
        at = sens - past / x_dot[coordinate] * (carried[9] - sens) / self.dt
        return at - np.outer(at[:, coordinate] / x_dot[coordinate], x_dot)

    def logs(self) -> tuple:
        rows = int(self.log_next[0])
        return (
            self.log_t[:rows].copy(),
            self.log_state[:rows].copy(),
            self.log_torque[:rows].copy(),
            self.log_sens[:rows].copy(),
        )


# The start state's head rates (a replay's start from the data, start.py): d state / d x0 along these entries.
START_RATES = {"start_head_vx_m_s": 16, "start_head_vy_m_s": 17, "start_head_yaw_rate_rad_s": 18}


def sensitivity_parameters() -> tuple:
    """The names a run can be differentiated by: the friction coefficients, the fitted parameters and
    diagnosis coordinates of every differentiable effect (effects.Effect.differentiable), and the start's
    head rates (START_RATES)."""
    names = [*FRICTION_NAMES, *START_RATES]
    for effect in LIBRARY.values():
        if effect.differentiable:
            names += [p.key for p in (*effect.fitted(), *effect.coordinate_space()) if p.key not in names]
    return tuple(names)


def sensitivity_directions(scenario: Scenario, names, size: int) -> tuple:
    """Per name, the change of the friction parameter vector (friction.py's layout) and of gravity's floor
    components per unit of it: central differences of the pure maps effects.model_setup and
    friction.friction_parameters (linear in all but the slope, whose error is ~1e-10); and the start state's
    change (the seeds of the sensitivities: a unit head rate for START_RATES). The tangent model (tangent.py)
    carries them through the run."""
    known = sensitivity_parameters()
    dparams, dgravity, seeds = np.zeros((len(names), size)), np.zeros((len(names), 2)), np.zeros((len(names), 32))
    base = model_setup(scenario.effects)
    for d, name in enumerate(names):
        if name not in known:
            raise ValueError(f"no sensitivity for '{name}' (known: {', '.join(known)})")
        if name in START_RATES:
            seeds[d, START_RATES[name]] = 1.0
            continue
        h = 1e-5 * max(1.0, abs(_value(scenario, name)))
        for sign in (1.0, -1.0):
            friction, effects = scenario.friction, scenario.effects
            if name in FRICTION_NAMES:
                friction = dataclasses.replace(friction, **{name: getattr(friction, name) + sign * h})
            else:
                effects = shifted(effects, name, sign * h)
            setup = model_setup(effects)
            if (setup.payload_module, setup.payload_kg) != (base.payload_module, base.payload_kg) or setup.extra_forces:
                raise ValueError(f"no sensitivity for '{name}': it changes the masses or adds a Python force")
            params = friction_parameters(
                friction=friction,
                sgn_smoothing_m_s=scenario.numerics.sgn_smoothing_m_s,
                setup=setup,
                geometry=plant_numbers().geometry,
            )
            dparams[d] += sign * params / (2 * h)
            dgravity[d] += sign * setup.gravity[:2] / (2 * h)
    return dparams, dgravity, seeds


def _value(scenario: Scenario, name: str) -> float:
    if name in FRICTION_NAMES:
        return getattr(scenario.friction, name)
    effect = coordinate_owner(name)
    values = effect_values(scenario.effects, effect)
    return values[name] if name in values else effect.coordinates(values)[name]


def _log_schedule(period: float, t_end: float, dt: float) -> tuple:
    """The loggers' times (every `period` from 0 to t_end; every update if 0) and the state index each records."""
    if period > 0:
        log_t = np.arange(int(math.floor(t_end / period + 1e-9)) + 1) * period
        return log_t, np.array([_updates_before(t, dt) for t in log_t], dtype=np.int64)
    steps = np.arange(_updates_before(t_end, dt) + 1, dtype=np.int64)
    return steps * dt, steps
