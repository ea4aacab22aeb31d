"""Typed configuration: the dataclasses of a scenario, and the constants every module shares.

Degrees appear only in fields whose names end in _deg / _deg_s (what a user types); everything else
is SI. Library code converts to radians once, where it reads the field (e.g. gait.serpenoid_parameters).
"""

import dataclasses
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
NUM_JOINTS = 13
GRAVITY_M_S2 = 9.81  # m/s^2, the normal force m g of Eqs. 4-5
JOINT_LIMIT_DEG = 38.0
Z95 = 1.96  # every reported 95% interval is the value +- Z95 standard errors (normal, Wald)
FAILURE_MODES = ("free", "locked", "weak")
TRUTH_MODELS = ("drake", "reference")  # what synthesize makes campaigns with (synthesize.py)
START_MODES = ("rest", "fit")  # where a replay takes the head's rates at t = 0 from (compare.py, start.py)


class Rc1Error(Exception):
    """A user-facing error: its message is one line naming the file, key and problem."""


@dataclasses.dataclass
class JointGait:
    """Per-joint override of the serpenoid parameters (unset fields keep the gait's values)."""

    joint: int = 0  # 1-based, 1 = between head and module 2
    amplitude_deg: float | None = None
    frequency_deg_s: float | None = None
    phase_deg: float | None = None  # phi_i itself, replacing offset + step rule
    bias_deg: float | None = None


@dataclasses.dataclass
class Gait:
    """Serpenoid gait, paper Eqs. 3 and 7: theta_i(t) = A_i sin(omega_i t - phi_i) + B_i,
    phi_i = (i - 1) * phase_step - phase_offset (the offset advances the whole wave)."""

    amplitude_deg: float = 38.0
    frequency_deg_s: float = 140.0
    phase_step_deg: float = 40.0
    phase_offset_deg: float = 0.0
    bias_deg: float = 0.0
    joints: list[JointGait] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class Servo:
    """Per-joint PID servo gains; the torque limit is the SDF's effort limit (1.19 N m).

    The paper gives no servo gains. Kp saturates the 1.19 N m servo at a 3.4 deg error; Kd is about
    the HS5645MG's stall torque over its no-load speed (1.19 N m / ~6 rad/s), the damping of its
    motor's back-EMF; Ki removes a steady error within a few gait periods. With these the working
    joints track the nominal gait to 0.53 deg RMS (3.6 deg at worst).
    """

    kp_Nm_per_rad: float = 20.0
    ki_Nm_per_rad_s: float = 5.0
    kd_Nm_s_per_rad: float = 0.2
    torque_limit_Nm: float | None = None  # None: the SDF's effort limit
    # The proportional term acts on the reference predicted this far ahead, theta + lead theta_dot; with the
    # lead one time step and a stiff Kp the joint is the paper's kinematic joint (replay.REPLAY_SERVO).
    lead_s: float = 0.0


@dataclasses.dataclass
class Friction:
    """The paper's five friction coefficients; defaults are its identified set (section 4)."""

    c_joint: float = 0.045  # N m s/rad, viscous friction of a failed joint
    mu_lat: float = 1.5  # Coulomb, lateral (Eq. 4)
    mu_long: float = 0.12  # Coulomb, longitudinal (Eq. 5)
    c_lat: float = 3.75  # N s/m, viscous, lateral (Eq. 4)
    c_long: float = 0.14  # N s/m, viscous, longitudinal (Eq. 5)


FRICTION_NAMES = tuple(f.name for f in dataclasses.fields(Friction))
SERVO_NAMES = tuple(f.name for f in dataclasses.fields(Servo))
# The measurement channels' standard deviations that standardize a replay's residuals (sysid.residual.trial_residual,
# start.py): the hand-measured final position, the IMU's yaw rate, the camera's head position.
RESIDUAL_SIGMAS = {"final_m": 0.01, "yaw_rate_rad_s": 0.05, "camera_m": 0.01}


@dataclasses.dataclass
class Failure:
    """A joint failing at time_s. Modes: `free` (the paper's: the servo is unpowered, only c_joint and
    the joint limits act), `locked` (held at the angle it had when it failed, as in Mehta et al.),
    `weak` (the servo still tracks, with its torque limited to weak_torque_Nm)."""

    joint: int = 0  # 1-based
    time_s: float = 0.0
    mode: str = "free"
    weak_torque_Nm: float = 0.4


@dataclasses.dataclass
class Start:
    """Head centre position and the heading of the body's mean axis (mean of the 14 module yaws)."""

    x_m: float = 0.0
    y_m: float = 0.0
    heading_deg: float = 0.0


@dataclasses.dataclass
class Stop:
    """Stop at whichever comes first; null disables a rule."""

    line_x_m: float | None = 3.18
    revolutions: float | None = 2.0
    time_limit_s: float = 30.0
    # Run on to time_limit_s past the line or the turns, their instant and state recorded (Run.event_t): a replay
    # then covers every sample its trial measured, so its residuals have the same entries whatever the model.
    run_through: bool = False


@dataclasses.dataclass
class Numerics:
    time_step_s: float = 1e-3
    sgn_smoothing_m_s: float = 0.001
    log_period_s: float = 0.01


@dataclasses.dataclass
class HeadingControl:
    """Closed-loop bias (the paper's proposal in section 5): every joint's bias is
    -clamp(kp e + ki int(e) dt, +-bias_limit), e = heading_ref - (mean module yaw), so the snake
    turns back toward its reference heading; the integral also cancels the lateral offset that
    a heading error built up. Zero gains: no controller in the Diagram."""

    kp: float = 0.0  # rad of bias per rad of heading error
    ki_per_s: float = 0.0
    bias_limit_deg: float = 5.0
    heading_ref_deg: float = 0.0

    @property
    def active(self) -> bool:
        return self.kp != 0.0 or self.ki_per_s != 0.0


@dataclasses.dataclass
class Scenario:
    gait: Gait = dataclasses.field(default_factory=Gait)
    servo: Servo = dataclasses.field(default_factory=Servo)
    friction: Friction = dataclasses.field(default_factory=Friction)
    # Physical effects beyond the paper's model by parameter key (rc1_drake/effects/); empty is the paper's model.
    effects: dict[str, float] = dataclasses.field(default_factory=dict)
    failures: list[Failure] = dataclasses.field(default_factory=list)
    start: Start = dataclasses.field(default_factory=Start)
    heading_control: HeadingControl = dataclasses.field(default_factory=HeadingControl)
    stop: Stop = dataclasses.field(default_factory=Stop)
    numerics: Numerics = dataclasses.field(default_factory=Numerics)

    @property
    def failed_joints(self) -> list[int]:
        return sorted({f.joint for f in self.failures})
