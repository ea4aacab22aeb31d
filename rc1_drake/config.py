"""Typed configuration: named scenarios in YAML, loaded with Drake's yaml_load_typed.

Degrees appear only in fields whose names end in _deg / _deg_s (what a user types); everything else
is SI. Library code converts once, through the *_rad accessors here.
"""

import dataclasses
import math
from pathlib import Path
from typing import Dict, List, Optional

from pydrake.common.yaml import yaml_load_typed

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENARIOS = REPO_ROOT / "scenarios" / "rc1.yaml"
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
    amplitude_deg: Optional[float] = None
    frequency_deg_s: Optional[float] = None
    phase_deg: Optional[float] = None  # phi_i itself, replacing offset + step rule
    bias_deg: Optional[float] = None


@dataclasses.dataclass
class Gait:
    """Serpenoid gait, paper Eqs. 3 and 7: theta_i(t) = A_i sin(omega_i t - phi_i) + B_i,
    phi_i = (i - 1) * phase_step - phase_offset (the offset advances the whole wave)."""

    amplitude_deg: float = 38.0
    frequency_deg_s: float = 140.0
    phase_step_deg: float = 40.0
    phase_offset_deg: float = 0.0
    bias_deg: float = 0.0
    joints: List[JointGait] = dataclasses.field(default_factory=list)


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
    torque_limit_Nm: Optional[float] = None  # None: the SDF's effort limit
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
# The measurement channels' standard deviations that standardize a replay's residuals (identify.trial_residual,
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

    line_x_m: Optional[float] = 3.18
    revolutions: Optional[float] = 2.0
    time_limit_s: float = 30.0


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
    # Physical effects beyond the paper's model by parameter key (effects.py); empty is the paper's model.
    effects: Dict[str, float] = dataclasses.field(default_factory=dict)
    failures: List[Failure] = dataclasses.field(default_factory=list)
    start: Start = dataclasses.field(default_factory=Start)
    heading_control: HeadingControl = dataclasses.field(default_factory=HeadingControl)
    stop: Stop = dataclasses.field(default_factory=Stop)
    numerics: Numerics = dataclasses.field(default_factory=Numerics)

    @property
    def failed_joints(self) -> List[int]:
        return sorted({f.joint for f in self.failures})


def load_scenario(name: str, *, filename=DEFAULT_SCENARIOS) -> Scenario:
    """The scenario `name` of a YAML file of named scenarios, validated."""
    path = Path(filename)
    if not path.is_file():
        raise Rc1Error(f"{path}: no such scenario file")
    names = list_scenarios(path)
    if name not in names:
        raise Rc1Error(f"{path}: no scenario named '{name}' (known: {', '.join(names)})")
    try:
        scenario = yaml_load_typed(schema=Scenario, filename=str(path), child_name=name)
    except Exception as e:  # noqa: BLE001 - any failure here is a malformed file, reported in one line
        raise Rc1Error(f"{path}: scenario '{name}': {_one_line(e) or type(e).__name__}") from None
    validate(scenario, where=f"{path}: scenario '{name}'")
    return scenario


@dataclasses.dataclass
class ModelFile:
    """What a fit or a diagnosis found: friction coefficients and physical effects (effects.py); read by
    `--model-file` of run, compare, sweep and identify. A file holding only the five friction
    coefficients at the top level (the older friction file) is read too."""

    friction: Friction = dataclasses.field(default_factory=Friction)
    effects: Dict[str, float] = dataclasses.field(default_factory=dict)


def load_model_file(path) -> ModelFile:
    """The model file at `path`, validated; Rc1Error names the file and the problem."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise Rc1Error(f"{path}: no such model file")
    try:
        top = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as e:
        raise Rc1Error(f"{path}: not valid YAML: {_one_line(e)}") from None
    flat = isinstance(top, dict) and bool(top) and set(top) <= set(FRICTION_NAMES)
    try:
        model = (ModelFile(friction=yaml_load_typed(schema=Friction, filename=str(path))) if flat
                 else yaml_load_typed(schema=ModelFile, filename=str(path)))
    except Exception as e:  # noqa: BLE001 - any parse failure is a malformed file, reported in one line
        raise Rc1Error(f"{path}: {_one_line(e) or type(e).__name__}") from None
    validate(Scenario(friction=model.friction, effects=model.effects), where=str(path))
    return model


def model_to_yaml(friction: Friction, effects: Optional[Dict[str, float]] = None, *, comment: str = "") -> str:
    lines = [f"# {comment or 'Model file'}: friction (rc1_drake.config.Friction) and effects (rc1 effects);",
             "# read with --model-file.", "friction:"]
    lines += [f"  {name}: {getattr(friction, name):.6g}" for name in FRICTION_NAMES]
    lines += ["effects:" + ("" if effects else " {}")]
    lines += [f"  {key}: {value:.6g}" for key, value in (effects or {}).items()]
    return "\n".join(lines) + "\n"


def list_scenarios(filename=DEFAULT_SCENARIOS) -> List[str]:
    import yaml  # Drake depends on PyYAML; only the top-level keys are read here

    with open(filename) as f:
        try:
            data = yaml.safe_load(f)
        except yaml.YAMLError as e:
            raise Rc1Error(f"{filename}: not valid YAML: {_one_line(e)}") from None
    if not isinstance(data, dict):
        raise Rc1Error(f"{filename}: expected a mapping of scenario names to scenarios")
    return list(data)


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split())


def validate(s: Scenario, *, where: str = "scenario") -> Scenario:
    """Raise Rc1Error naming the first bad key; return the scenario unchanged otherwise."""

    def bad(key: str, problem: str):
        raise Rc1Error(f"{where}: {key}: {problem}")

    def finite(key, value, *, positive=False, nonneg=False):
        if value is None or not math.isfinite(value):
            bad(key, f"must be a finite number, got {value}")
        if positive and value <= 0:
            bad(key, f"must be > 0, got {value}")
        if nonneg and value < 0:
            bad(key, f"must be >= 0, got {value}")

    g = s.gait
    finite("gait.amplitude_deg", g.amplitude_deg)
    finite("gait.frequency_deg_s", g.frequency_deg_s, nonneg=True)
    finite("gait.phase_step_deg", g.phase_step_deg)
    finite("gait.phase_offset_deg", g.phase_offset_deg)
    finite("gait.bias_deg", g.bias_deg)
    for k, jg in enumerate(g.joints):
        if not 1 <= jg.joint <= NUM_JOINTS:
            bad(f"gait.joints[{k}].joint", f"must be 1..{NUM_JOINTS}, got {jg.joint}")
        for f in ("amplitude_deg", "frequency_deg_s", "phase_deg", "bias_deg"):
            if getattr(jg, f) is not None:
                finite(f"gait.joints[{k}].{f}", getattr(jg, f))
    for f in dataclasses.fields(Servo):
        if getattr(s.servo, f.name) is not None:
            finite(f"servo.{f.name}", getattr(s.servo, f.name), nonneg=True)
    for name in FRICTION_NAMES:
        finite(f"friction.{name}", getattr(s.friction, name), nonneg=True)
    from .effects import validate_effects  # effects.py builds on this module

    validate_effects(s.effects, where=where)
    seen = set()
    for k, fail in enumerate(s.failures):
        if not 1 <= fail.joint <= NUM_JOINTS:
            bad(f"failures[{k}].joint", f"must be 1..{NUM_JOINTS}, got {fail.joint}")
        if fail.joint in seen:
            bad(f"failures[{k}].joint", f"joint {fail.joint} is listed twice")
        seen.add(fail.joint)
        finite(f"failures[{k}].time_s", fail.time_s, nonneg=True)
        finite(f"failures[{k}].weak_torque_Nm", fail.weak_torque_Nm, nonneg=True)
        if fail.mode not in FAILURE_MODES:
            bad(f"failures[{k}].mode", f"unknown mode '{fail.mode}' (known: {', '.join(FAILURE_MODES)})")
    finite("start.x_m", s.start.x_m)
    finite("start.y_m", s.start.y_m)
    finite("start.heading_deg", s.start.heading_deg)
    if s.stop.line_x_m is not None:
        finite("stop.line_x_m", s.stop.line_x_m)
        if s.stop.line_x_m <= s.start.x_m:
            bad("stop.line_x_m", f"the line ({s.stop.line_x_m} m) must lie ahead of the start x ({s.start.x_m} m)")
    if s.stop.revolutions is not None:
        finite("stop.revolutions", s.stop.revolutions, positive=True)
    finite("stop.time_limit_s", s.stop.time_limit_s, positive=True)
    n = s.numerics
    finite("numerics.time_step_s", n.time_step_s, positive=True)
    if n.time_step_s > 0.01:
        bad("numerics.time_step_s", f"{n.time_step_s} s is too coarse for the wheel friction (<= 0.01 s)")
    finite("numerics.sgn_smoothing_m_s", n.sgn_smoothing_m_s, positive=True)
    finite("numerics.log_period_s", n.log_period_s, nonneg=True)
    return s
