"""The experiment of paper section 4: start configuration, stop rules, and simulate() -> Run.

At t = 0 the joints are at the serpenoid angles and rates, the head centre at the start point, the
body's mean axis (the mean of the 14 module yaws) along the start heading, and the body otherwise at
rest: its centre of mass does not move and its mean axis does not turn. The run stops when the head
centre crosses the line x = line_x_m (outcome "crossed"), when the head's yaw has turned by
`revolutions` full turns ("circling", the failures near the head), or at the time limit
("timed_out").
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus

from .config import JOINT_LIMIT_DEG, Rc1Error, Scenario
from .diagram import RC1Diagram, build_diagram, build_key
from .effects import apply_effects, commanded_gait
from .gait import serpenoid, serpenoid_parameters
from .kinematics import ChainGeometry, module_motion, module_yaws


def rest_state(head_xy, head_yaw: float, q, q_dot, geometry: ChainGeometry) -> np.ndarray:
    """Plant state with the given head pose and joint motion, and the body otherwise at rest:
    the head's velocity is chosen so that the centre of mass does not move and the mean module yaw
    does not turn."""
    head_rate = -module_yaws(0.0, q_dot).mean()
    x = np.concatenate([head_xy, [head_yaw], q, [0.0, 0.0, head_rate], q_dot])
    _, _, _, v = module_motion(x, geometry)  # module velocities with the head centre at rest
    m = geometry.module_mass
    head_v = -(m * v).sum() / m.sum()
    x[16:18] = head_v.real, head_v.imag
    return x


def initial_state(scenario: Scenario, geometry: ChainGeometry) -> np.ndarray:
    """Plant state [x, y, yaw, q; vx, vy, w, q_dot] at t = 0 (see the module docstring)."""
    q, q_dot = serpenoid(0.0, commanded_gait(scenario.gait, scenario.effects))
    # The robot starts within its joint limits: a biased gait can command more at t = 0 (bias 4 deg: joint 8
    # at 41.4 deg), which the plant's limit constraint would throw back in its first steps and the sensors
    # record as an angle RC1 cannot reach. A joint at its limit cannot be moving outward.
    limit = math.radians(JOINT_LIMIT_DEG)
    outward = (np.abs(q) >= limit) & (q * q_dot > 0.0)
    q, q_dot = np.clip(q, -limit, limit), np.where(outward, 0.0, q_dot)
    head_yaw = math.radians(scenario.start.heading_deg) - module_yaws(0.0, q).mean()
    return rest_state([scenario.start.x_m, scenario.start.y_m], head_yaw, q, q_dot, geometry)


def configure_context(built: RC1Diagram, context, scenario: Scenario, initial=None) -> None:
    """Reset `context` to t = 0 and write the per-run parts of `scenario` into it; the plant starts
    from `initial` if given, else from initial_state(scenario)."""
    built.diagram.SetDefaultContext(context)
    context.SetTime(0.0)
    apply_effects(
        built,
        context,
        scenario.effects,
        friction=scenario.friction,
        sgn_smoothing_m_s=scenario.numerics.sgn_smoothing_m_s,
    )
    built.failure_switch.reset(context, scenario.servo.torque_limit_Nm)
    if built.gait_bias is not None:
        bias = serpenoid_parameters(commanded_gait(scenario.gait, scenario.effects))[3]  # a sensor fault moves it
        built.gait_bias.get_mutable_source_value(built.gait_bias.GetMyMutableContextFromRoot(context)).SetFromVector(
            bias
        )
    plant_context = built.plant.GetMyMutableContextFromRoot(context)
    x0 = initial_state(scenario, built.rc1.geometry) if initial is None else initial
    built.plant.SetPositionsAndVelocities(plant_context, x0)
    for failure in scenario.failures:  # after the state: locking a joint zeroes its rate
        if failure.time_s == 0.0:
            built.failure_switch.fail(context, failure)
    for logger in (built.state_logger, built.torque_logger):
        logger.FindMutableLog(context).Clear()


@dataclasses.dataclass
class Run:
    """A finished run: logs (rows = samples) and how it ended."""

    scenario: Scenario
    t: np.ndarray  # (N,) s
    state: np.ndarray  # (N, 32) plant state [x, y, yaw, q1..q13; vx, vy, w, q1_dot..q13_dot]
    servo_torque: np.ndarray  # (N, 13) N m, what the servos applied (0 once a joint has failed)
    stop_reason: str  # "crossed", "circling" or "timed_out"
    wall_time_s: float
    geometry: ChainGeometry  # of the plant that made the run
    # Forward sensitivities d state / d parameter (N, P, 32) for the parameters named (compiled engine only).
    sensitivity: np.ndarray | None = None
    sensitivity_names: tuple = ()
    # A run through its stop event (Stop.run_through): when the line or the turns were reached (None: never), the
    # state then (the first update at or past it) and its sensitivities, which follow the event's time (P, 32).
    event_t: float | None = None
    event_state: np.ndarray | None = None
    event_sensitivity: np.ndarray | None = None

    def residual_jacobian(self, residual_of, residual) -> np.ndarray:
        """d residual_of(run) / d parameter, one column per sensitivity_names, for a residual linear in the logged
        states (interpolated positions and rates) and the event's state: the residual of the run moved along each
        sensitivity, less `residual` (residual_of(self))."""
        columns = []
        for p in range(len(self.sensitivity_names)):
            moved = dataclasses.replace(self, state=self.state + self.sensitivity[:, p])
            if self.event_state is not None:
                moved.event_state = self.event_state + self.event_sensitivity[p]
            columns.append(residual_of(moved) - residual)
        return np.column_stack(columns) if columns else np.zeros((len(residual), 0))

    @property
    def end_t(self) -> float:
        """When the experiment ended: its stop event, else its last log."""
        return float(self.t[-1]) if self.event_t is None else self.event_t

    @property
    def final_head_xy(self) -> np.ndarray:
        """The head's position where the experiment ended (end_t): what the paper measures by hand."""
        return self.head_xy[-1] if self.event_state is None else self.event_state[0:2]

    def until_event(self) -> Run:
        """This run as the experiment saw it: its logs up to the stop event, closed by the event's state."""
        if self.event_t is None:
            return self
        keep = self.t < self.event_t - 1e-12
        # The servos' torque at the first log at or past the event; the last log where the event came after it
        # (a run through its event may reach it in the steps past its last log).
        at_event = min(int(np.searchsorted(self.t, self.event_t)), len(self.t) - 1)
        sensitivity = None
        if self.sensitivity is not None:
            sensitivity = np.concatenate([self.sensitivity[keep], self.event_sensitivity[None]])
        return dataclasses.replace(
            self,
            t=np.append(self.t[keep], self.event_t),
            state=np.vstack([self.state[keep], self.event_state]),
            servo_torque=np.vstack([self.servo_torque[keep], self.servo_torque[at_event]]),
            sensitivity=sensitivity,
            event_t=None,
            event_state=None,
            event_sensitivity=None,
        )

    @property
    def head_xy(self):
        return self.state[:, 0:2]

    @property
    def head_yaw(self):
        return self.state[:, 2]

    @property
    def q(self):
        return self.state[:, 3:16]

    @property
    def q_dot(self):
        return self.state[:, 19:32]

    @property
    def head_yaw_rate(self):
        return self.state[:, 18]


class Session:
    """One built Diagram with its Simulator, reused for every run whose build_key matches, built anew for one that
    does not (the Drake engine; engine.CompiledSession is its compiled twin)."""

    engine = "drake"

    def __init__(self, scenario: Scenario, *, joint_reference=None):
        """joint_reference: a Drake trajectory of the 13 joint angles, or a replay.JointReference."""
        trajectory = getattr(joint_reference, "trajectory", joint_reference)
        self.built = build_diagram(scenario, joint_reference=trajectory)
        self.simulator = Simulator(self.built.diagram)
        self.joint_reference = self.following = trajectory  # what it was built with (its key), what it follows

    @property
    def geometry(self) -> ChainGeometry:
        return self.built.rc1.geometry

    def set_joint_reference(self, joint_reference) -> None:
        """Follow another reference (same kind as the one this Session was built with) from the next run."""
        self.following = getattr(joint_reference, "trajectory", joint_reference)
        self.built.diagram.GetSubsystemByName("joint_reference").UpdateTrajectory(self.following)

    def simulate(self, scenario: Scenario, *, initial=None, sensitivities=()) -> Run:
        """Run `scenario` (from `initial`, a plant state, if given) on this Session's Diagram."""
        if sensitivities:
            raise Rc1Error("sensitivities need the compiled engine (--engine compiled)")
        if build_key(scenario, self.joint_reference) != self.built.build_key:  # gait, servo gains or numerics
            self.built = build_diagram(scenario, joint_reference=self.joint_reference)
            self.simulator = Simulator(self.built.diagram)
            if self.following is not self.joint_reference:
                self.set_joint_reference(self.following)
        built, simulator = self.built, self.simulator
        context = simulator.get_mutable_context()
        configure_context(built, context, scenario, initial)
        plant = built.plant
        plant_context = plant.GetMyContextFromRoot(context)
        yaw0 = plant.GetPositions(plant_context)[2]
        line = scenario.stop.line_x_m
        turn = None if scenario.stop.revolutions is None else 2 * math.pi * scenario.stop.revolutions
        reason, event = ["timed_out"], {}
        through = scenario.stop.run_through

        def monitor(root_context):
            q = plant.GetPositions(plant_context)
            if not np.isfinite(q[0]):
                return EventStatus.Failed(built.diagram, "the state is not finite")
            if event:
                return EventStatus.Succeeded()
            if line is not None and q[0] >= line:
                reason[0] = "crossed"
            elif turn is not None and abs(q[2] - yaw0) >= turn:
                reason[0] = "circling"
            else:
                return EventStatus.Succeeded()
            if through:
                event["t"], event["state"] = root_context.get_time(), plant.GetPositionsAndVelocities(plant_context)
                return EventStatus.Succeeded()
            return EventStatus.ReachedTermination(built.diagram, reason[0])

        # Later failures split the run: advance to the failure time, switch, go on.
        t_end = scenario.stop.time_limit_s
        later = sorted((f for f in scenario.failures if 0.0 < f.time_s < t_end), key=lambda f: f.time_s)
        simulator.set_monitor(monitor)
        simulator.Initialize()
        start = time.perf_counter()
        try:
            for failure in later:
                simulator.AdvanceTo(failure.time_s)
                if reason[0] != "timed_out" and not through:
                    break
                built.failure_switch.fail(context, failure)
            if reason[0] == "timed_out" or through:
                simulator.AdvanceTo(t_end)
        except RuntimeError as e:
            raise Rc1Error(f"simulation failed at t = {context.get_time():.3f} s: {' '.join(str(e).split())}") from None
        finally:
            simulator.clear_monitor()
        wall = time.perf_counter() - start

        # Copies: the logs live in the context, which the next run of this Session reuses.
        t = np.array(built.state_logger.FindLog(context).sample_times())
        state = np.array(built.state_logger.FindLog(context).data().T)
        torque = np.array(built.torque_logger.FindLog(context).data().T)
        t_stop = context.get_time()
        if len(t) == 0 or t[-1] < t_stop - 1e-12:  # close the logs at the exact stop time
            t = np.append(t, t_stop)
            state = np.vstack([state, plant.GetPositionsAndVelocities(plant_context)])
            torque = np.vstack([torque, built.diagram.GetOutputPort("servo_torque").Eval(context)])
        return Run(
            scenario=scenario,
            t=t,
            state=state,
            servo_torque=torque,
            stop_reason=reason[0],
            wall_time_s=wall,
            geometry=built.rc1.geometry,
            event_t=event.get("t"),
            event_state=event.get("state"),
        )


def simulate(*, scenario: Scenario, session: Session | None = None) -> Run:
    """Run the experiment of `scenario`; pass a Session to reuse its Diagram and Simulator."""
    if session is None or session.built.build_key != build_key(scenario):
        session = Session(scenario)
    return session.simulate(scenario)
