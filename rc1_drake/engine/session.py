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

from ..config import NUM_JOINTS, Rc1Error, Scenario
from ..effects import commanded_gait, model_setup
from ..friction import FAILED, FREE, LOCKED, friction_parameters
from ..gait import serpenoid_parameters
from ..protocol import Run, initial_state
from .dynamics import plant_numbers
from .run import CIRCLING, CROSSED, NOT_FINITE, REFERENCE, SERPENOID, _advance

_REASON = {CROSSED: "crossed", CIRCLING: "circling"}
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
    def from_trajectory(cls, trajectory) -> "HermiteReference":
        """The knots of a Drake PiecewisePolynomial of cubic (or lower) segments that is C1 at its breaks."""
        if trajectory.getSegmentPolynomialDegree(0) > 3:
            raise ValueError("the compiled engine follows C1 cubic joint references (PiecewisePolynomial.CubicHermite)")
        t = np.array(trajectory.get_segment_times())
        derivative = trajectory.derivative(1)
        return cls(t=t, q=np.array([trajectory.value(s).ravel() for s in t]),
                   q_dot=np.array([derivative.value(s).ravel() for s in t]))


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
            self.joint_reference = HermiteReference(t=np.asarray(joint_reference.t, dtype=float),
                                                    q=np.asarray(joint_reference.q, dtype=float),
                                                    q_dot=np.asarray(joint_reference.q_dot, dtype=float))
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
        from ..protocol import Session

        if self._drake is None:
            _warn_once("an effect adds a Python force (ModelSetup.extra_forces), which the compiled engine "
                       "cannot call: such runs use the Drake engine")
            self._drake = Session(scenario, joint_reference=self._trajectory())
        return self._drake.simulate(scenario, initial=initial)

    def simulate(self, scenario: Scenario, *, initial=None) -> Run:
        """Run `scenario` (from `initial`, a plant state, if given), as protocol.Session.simulate does."""
        numbers = self.numbers
        geometry = numbers.geometry
        setup = model_setup(scenario.effects)
        if setup.extra_forces:
            return self._on_drake(scenario, initial)
        dt = scenario.numerics.time_step_s
        params = friction_parameters(friction=scenario.friction, sgn_smoothing_m_s=scenario.numerics.sgn_smoothing_m_s,
                                     setup=setup, geometry=geometry)
        limit = scenario.servo.torque_limit_Nm
        power = numbers.effort_limit.copy() if limit is None else np.full(NUM_JOINTS, float(limit))
        locked = np.zeros(NUM_JOINTS, dtype=np.bool_)
        x = np.array(initial_state(scenario, geometry) if initial is None else initial, dtype=float)
        if x.shape != (32,):
            raise ValueError(f"initial state must have 32 entries, got shape {x.shape}")
        t_end = scenario.stop.time_limit_s
        steps = _updates_before(t_end, dt)
        later = sorted((f for f in scenario.failures if 0.0 < f.time_s < t_end), key=lambda f: f.time_s)
        for failure in scenario.failures:
            if failure.time_s == 0.0:  # as configure_context: the switch acts on the start state
                self._fail(failure, params, power, locked, x)

        period = scenario.numerics.log_period_s
        if period > 0:
            log_t = np.arange(int(math.floor(t_end / period + 1e-9)) + 1) * period
            log_steps = np.array([_updates_before(t, dt) for t in log_t], dtype=np.int64)
        else:
            log_steps = np.arange(steps + 1, dtype=np.int64)
            log_t = log_steps * dt
        log_state = np.zeros((len(log_steps), 32))
        log_torque = np.zeros((len(log_steps), NUM_JOINTS))

        source, gait, heading, knots = self._source(scenario)
        stop = scenario.stop
        stop_row = np.array([np.nan if stop.line_x_m is None else stop.line_x_m,
                             np.inf if stop.revolutions is None else 2 * math.pi * stop.revolutions, x[2]])
        gravity = setup.gravity
        model = np.array([gravity[0], gravity[1], float(bool(gravity[0] or gravity[1]))])
        s = scenario.servo
        gains = np.array([s.kp_Nm_per_rad, s.ki_Nm_per_rad_s, s.kd_Nm_s_per_rad])
        constant = (log_steps, log_state, log_torque, source, gait, heading, *knots, gains, stop_row, model,
                    numbers.masses(setup.payload_module, setup.payload_kg), numbers.central_yaw_inertia, numbers.com,
                    numbers.effort_limit, numbers.lower_limit, numbers.upper_limit, *geometry.arrays)
        carry = [x, np.zeros(NUM_JOINTS), np.zeros(1), np.zeros(1, dtype=np.int64), params, power, locked,
                 np.zeros(1, dtype=np.int64), np.zeros(NUM_JOINTS)]

        def advance(carry, k0, k1, t_first=np.nan):
            x, z, zh, seg, params, power, locked, log_next, last = carry
            log_steps, *rest = constant
            return _advance(x, z, zh, seg, k0, k1, t_first, dt, np.zeros(16), params, power, locked, log_steps,
                            log_t, log_next, last, *rest)

        def probe(k, t, logs):
            """The step at k without taking it: its servo torque, and the logs due then if `logs`."""
            copy = [np.array(c, copy=True) for c in carry]
            if not logs:
                copy[7][0] = len(log_steps)
            advance(copy, k, k + 1, t)
            carry[7][0] = copy[7][0]
            return copy[8]

        start = time.perf_counter()
        status, k = 0, 0
        for failure in later:  # as Session: advance to the failure, switch, go on
            k_fail = _updates_before(failure.time_s, dt)
            status, k = advance(carry, k, k_fail)
            if status:
                break
            due = carry[7][0]
            if due < len(log_steps) and log_steps[due] == k and log_t[due] <= failure.time_s:
                probe(k, failure.time_s, True)  # a log at t_f itself is published by AdvanceTo(t_f): before the switch
            self._fail(failure, carry[4], carry[5], carry[6], carry[0])
        if not status:
            status, k = advance(carry, k, steps)
        wall = time.perf_counter() - start
        t_stop = k * dt if status != 0 else t_end
        if status == NOT_FINITE:
            raise Rc1Error(f"simulation failed at t = {t_stop:.3f} s: the state is not finite")
        rows = int(carry[7][0])
        t, state, torque = log_t[:rows], log_state[:rows], log_torque[:rows]
        if rows == 0 or t[-1] < t_stop - 1e-12:  # close the logs at the exact stop time, as the Drake engine does
            t = np.append(t, t_stop)
            state = np.vstack([state, carry[0]])
            torque = np.vstack([torque, probe(k, t_stop, False)])
        return Run(scenario=scenario, t=t, state=state.copy(), servo_torque=torque.copy(),
                   stop_reason=_REASON.get(status, "timed_out"), wall_time_s=wall, geometry=geometry)

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
            return (REFERENCE, np.zeros((4, NUM_JOINTS)), np.zeros(5 + 16),
                    (np.ascontiguousarray(ref.t, dtype=float), np.ascontiguousarray(ref.q, dtype=float),
                     np.ascontiguousarray(ref.q_dot, dtype=float)))
        amp, omega, phase, _ = serpenoid_parameters(commanded_gait(scenario.gait, scenario.effects))
        bias = serpenoid_parameters(scenario.gait)[3]
        hc = scenario.heading_control
        heading = np.zeros(5 + 16)
        if hc.active:
            heading[:5] = [1.0, hc.kp, hc.ki_per_s, math.radians(hc.bias_limit_deg), math.radians(hc.heading_ref_deg)]
            heading[5 + 2] = 1.0  # mean module yaw = head yaw + sum_i (14 - i)/14 q_i (diagram.add_heading_control)
            heading[5 + 3:] = (NUM_JOINTS + 1 - np.arange(1, NUM_JOINTS + 1)) / (NUM_JOINTS + 1)
        empty = (np.zeros(2), np.zeros((2, NUM_JOINTS)), np.zeros((2, NUM_JOINTS)))
        return SERPENOID, np.array([amp, omega, phase, bias]), heading, empty
