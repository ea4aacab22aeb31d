"""Candidate effects beyond the paper's model: a library that a run, a synthesized truth, a fit or a diagnosis
adds by name. Most are physical; the sensor faults (Effect.sensor) leave the robot alone and change what its
sensors report (SensorModel): the data a truth is measured into, and what a replay is compared with.

A scenario's `effects:` mapping holds parameter values by key (`ground_slope_deg: 3.0`); a missing key
is 0 (or a setting's default), and every effect at 0 is the paper's model exactly (nested models).
Each effect is one small class: its parameters (bounds, and whether a fit estimates them or the user
sets them) and how it changes the model, by editing a ModelSetup (gravity, payload, friction-law
terms, wheel toe, explicit forces), for the commanded gait, the Gait, and for a sensor fault, the SensorModel.
`register()` adds a user's own; docs/effects.md shows one.

Sign conventions are the README's: world x toward the line, y left, z up; a wheel's +x rolls forward
(toward the head), +y is its left.
"""

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from .config import GRAVITY_M_S2, JOINT_LIMIT_DEG, NUM_JOINTS, Friction, Gait, JointGait, Rc1Error
from .discrepancy import NUM_TERMS, term_names


@dataclasses.dataclass(frozen=True)
class EffectParameter:
    key: str  # its key under `effects:`; the unit is in the name
    lower: float  # physical domain, and the bounds of a fit
    upper: float
    fitted: bool = True  # False: a setting the user chooses (which module, a reference speed), never fitted
    default: float = 0.0  # its value when the scenario leaves it out
    probe: float | None = None  # a small, clearly visible step for sensitivities (diagnose.py); None: 10% of the range

    @property
    def probe_step(self) -> float:
        return self.probe if self.probe is not None else 0.1 * (self.upper - self.lower)


@dataclasses.dataclass
class ModelSetup:
    """What the effects of a run change, gathered before it is written into the Diagram's context."""

    gravity: np.ndarray  # (3,) world, m/s^2
    payload_module: int = 0  # 1..14, 0: none
    payload_kg: float = 0.0
    lateral_asymmetry: float = 0.0
    longitudinal_asymmetry: float = 0.0
    stribeck_ratio: float = 0.0
    stribeck_speed_m_s: float = 0.01
    head_mu: float = 0.0
    joint_coulomb_Nm: float = 0.0
    stop_k: float = 0.0  # N m/rad, a failed joint's compliant stop (0: the plant's stiff limit alone)
    stop_d: float = 0.0  # N m s/rad
    stop_onset_rad: float = 0.0
    head_on_wheel2: float = 0.0  # head weights carried by module 2's wheel (a cantilevered head)
    tail_tether_N: float = 0.0  # a tether's Coulomb pull at the tail's end
    wheel_toe_rad: float = 0.0
    discrepancy: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(NUM_TERMS))  # discrepancy.py
    extra_forces: list[Callable] = dataclasses.field(default_factory=list)  # f(x) -> (16,) generalized force


@dataclasses.dataclass
class SensorModel:
    """What the sensors report of a motion, as the sensor faults make it (all at 0: the paper's perfect sensors).
    Synthesis measures a truth through it; a replay reads the potentiometers back through it and predicts the
    camera and the IMU through it (sysid.residual.trial_residual, compare.score_trial)."""

    angle_offsets_rad: np.ndarray  # (13,) the potentiometers read angle_gains * angle + angle_offsets_rad
    angle_gains: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(NUM_JOINTS))
    camera_delay_s: float = 0.0  # a frame stamped t shows the head at t - delay
    imu_scale: float = 1.0  # the IMU reports imu_scale * yaw rate + imu_bias
    imu_bias_rad_s: float = 0.0

    def potentiometers(self, q) -> np.ndarray:
        """What the potentiometers read of joint angles q (..., 13), rad."""
        return self.angle_gains * q + self.angle_offsets_rad

    @property
    def reads_angles(self) -> bool:
        """Whether the potentiometers read the angles as they are (no offset, no gain error)."""
        return not self.angle_offsets_rad.any() and bool(np.all(self.angle_gains == 1.0))

    def camera(self, t, run_t, run_xy_yaw) -> np.ndarray:
        """(len(t), k) the camera's report at sample times t of the run's (run_t, (N, k) head pose columns)."""
        seen = np.asarray(t, dtype=float) - self.camera_delay_s
        return np.column_stack([np.interp(seen, run_t, run_xy_yaw[:, i]) for i in range(run_xy_yaw.shape[1])])

    def imu(self, t, run_t, run_yaw_rate) -> np.ndarray:
        """The IMU's yaw rate at sample times t of the run's."""
        return self.imu_scale * np.interp(t, run_t, run_yaw_rate) + self.imu_bias_rad_s


class Effect:
    """A named physical effect. Subclasses set `name`, `parameters` (the first is the one `--effect
    NAME=VALUE` sets), `summary`, and override `configure` and/or `gait`."""

    name: str = ""
    parameters: tuple = ()
    summary: str = ""
    seen_in_replay: bool = True  # False: it acts only on runs driven by the gait command
    # False: it changes the chain's masses or the gait command, which the compiled engine's sensitivities
    # (engine/session.py) do not follow; its derivatives are taken by finite differences of runs.
    differentiable: bool = True
    failed_joints_only: bool = False  # True: it acts only in failed joints (a trial without one is unchanged)
    sensor: bool = False  # True: a measurement fault (the robot is the paper's; what its sensors report is not)
    # False: a candidate only when asked for (by name, or the `study` group): a mechanism whose rate in the
    # diagnosis is not measured yet, kept out of the default candidates whose rates docs/diagnosis.md reports.
    default_candidate: bool = True
    discrepancy: bool = False  # True: a term of the discrepancy model (discrepancy.py), for discovery, not a mechanism

    def configure(self, setup: ModelSetup, values: dict[str, float]) -> None:
        """Change `setup` for parameter `values` (all of this effect's keys present)."""

    def gait(self, gait: Gait, values: dict[str, float]) -> Gait:
        """The gait the joints are commanded to follow, for runs driven by the gait."""
        return gait

    def configure_sensors(self, sensors: SensorModel, values: dict[str, float]) -> None:
        """Change `sensors` for parameter `values` (a sensor fault's; physical effects leave them)."""

    @property
    def main(self) -> EffectParameter:
        return self.parameters[0]

    def fitted(self) -> list[EffectParameter]:
        return [p for p in self.parameters if p.fitted]

    def coordinates(self, values: dict[str, float]) -> dict[str, float]:
        """Coordinates in which the residuals change smoothly (and, near 0, linearly) with the effect; a
        diagnosis fits these. By default the fitted parameters themselves."""
        return {p.key: values[p.key] for p in self.fitted()}

    def coordinate_space(self) -> list[EffectParameter]:
        """The coordinates' bounds and probe steps (parameters named by coordinate)."""
        return self.fitted()

    def from_coordinates(self, coordinates: dict[str, float]) -> dict[str, float]:
        """The effect parameter values for `coordinates`."""
        return dict(coordinates)


class GroundSlope(Effect):
    name = "ground_slope"
    summary = "a tilted floor: gravity pulls every module downhill, the normal forces fall by cos(slope)"
    parameters = (
        EffectParameter("ground_slope_deg", 0.0, 20.0, probe=3.0),
        EffectParameter("ground_slope_direction_deg", -180.0, 180.0),
    )  # downhill, counter-clockwise from +x

    # A diagnosis fits the tilt as a vector (downhill x and y components, degrees): at slope 0 the
    # direction has no effect at all, and the residuals are smooth in the components. It searches only
    # floors a lab could have unnoticed (a 5 deg floor is a 1:11 ramp, steeper than a wheelchair ramp;
    # a spirit level sees 0.1 deg): free to 20 deg, a tilt absorbed what a lateral friction asymmetry does
    # to a turning gait (docs/diagnosis.md). A known ramp goes into the model file; the search then spans it.
    search_deg = 5.0

    def coordinates(self, values):
        slope, heading = values["ground_slope_deg"], math.radians(values["ground_slope_direction_deg"])
        return {"ground_slope_x_deg": slope * math.cos(heading), "ground_slope_y_deg": slope * math.sin(heading)}

    def coordinate_space(self):
        return [
            EffectParameter(f"ground_slope_{axis}_deg", -self.search_deg, self.search_deg, probe=3.0) for axis in "xy"
        ]

    def from_coordinates(self, coordinates):
        x, y = coordinates["ground_slope_x_deg"], coordinates["ground_slope_y_deg"]
        return {
            "ground_slope_deg": min(math.hypot(x, y), self.main.upper),
            "ground_slope_direction_deg": math.degrees(math.atan2(y, x)),
        }

    def configure(self, setup, values):
        slope, heading = math.radians(values["ground_slope_deg"]), math.radians(values["ground_slope_direction_deg"])
        setup.gravity = GRAVITY_M_S2 * np.array(
            [math.sin(slope) * math.cos(heading), math.sin(slope) * math.sin(heading), -math.cos(slope)]
        )


class LateralFrictionAsymmetry(Effect):
    name = "lateral_friction_asymmetry"
    summary = "the lateral Coulomb coefficient is mu_lat (1 + a) sliding left, mu_lat (1 - a) sliding right"
    parameters = (EffectParameter("lateral_friction_asymmetry", -0.9, 0.9, probe=0.2),)

    def configure(self, setup, values):
        setup.lateral_asymmetry = values["lateral_friction_asymmetry"]


class LongitudinalFrictionAsymmetry(Effect):
    name = "longitudinal_friction_asymmetry"
    summary = "rolling resistance mu_long (1 + a) rolling forward, mu_long (1 - a) rolling backward"
    parameters = (EffectParameter("longitudinal_friction_asymmetry", -0.9, 0.9, probe=0.2),)

    def configure(self, setup, values):
        setup.longitudinal_asymmetry = values["longitudinal_friction_asymmetry"]


class HeadDrag(Effect):
    name = "head_drag"
    summary = "the wheelless head slides on the floor: isotropic Coulomb friction mu m g at its centre"
    parameters = (EffectParameter("head_drag_mu", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.head_mu = values["head_drag_mu"]


class JointCoulombFriction(Effect):
    name = "joint_coulomb_friction"
    summary = "dry friction torque in a failed (free) joint, beside its viscous c_joint"
    failed_joints_only = True
    parameters = (EffectParameter("joint_coulomb_Nm", 0.0, 1.0, probe=0.05),)

    def configure(self, setup, values):
        setup.joint_coulomb_Nm = values["joint_coulomb_Nm"]


class CompliantStop(Effect):
    """The paper's joint-limit PD (section 3) in a failed joint: past the onset angle, a restoring torque
    -k (|q| - onset) sgn(q) - d q_dot (friction.compliant_stop), before the plant's stiff +-38 deg limit. The onset
    sits inside the limit so that the PD, not the stiff limit, is what a swinging joint meets: a 0.5 N m load
    compresses a 20 N m/rad stop by 1.4 deg, within the default 5 deg onset margin."""

    name = "compliant_stop"
    summary = "a failed joint meets a PD stop (stiffness, damping) from an onset inside its +-38 deg limit"
    failed_joints_only = True
    default_candidate = False
    differentiable = False  # the tangent model (engine/tangent.py) does not carry it
    parameters = (
        EffectParameter("stop_k_Nm_per_rad", 0.0, 200.0, probe=5.0),
        EffectParameter("stop_d_Nm_s_per_rad", 0.0, 2.0, default=0.05),
        EffectParameter("stop_margin_deg", 0.0, 20.0, fitted=False, default=5.0),
    )

    def configure(self, setup, values):
        setup.stop_k, setup.stop_d = values["stop_k_Nm_per_rad"], values["stop_d_Nm_s_per_rad"]
        setup.stop_onset_rad = math.radians(JOINT_LIMIT_DEG - values["stop_margin_deg"])


class HeadCantilever(Effect):
    """The wheelless head held off the floor by the four-bar linkage, rigid in pitch: module 2's wheel carries
    its weight, up to twice it when the head's centre is as far ahead of wheel 2 as wheel 3 is behind (the
    moment then lifts wheel 3 by the excess). 0 is the paper's model (the head's weight nowhere)."""

    name = "head_cantilever"
    summary = "module 2's wheel carries s head weights (up to 2: the head's moment), wheel 3 loses the excess over 1"
    default_candidate = False
    parameters = (EffectParameter("head_on_wheel2", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.head_on_wheel2 = values["head_on_wheel2"]


class TailTether(Effect):
    """RC1 was powered through one tether at its tail (paper section 2): the cable lying on the floor behind it
    drags the tail's end with its sliding friction (its weight on the floor times its friction coefficient),
    against the end's motion: an isotropic Coulomb force of T newtons there, in the implicit friction solve (both
    engines; friction.tail_end_jacobian). Outside the paper's model and the default candidates."""

    name = "tail_tether"
    summary = "a cable dragged behind the tail: a Coulomb force T against its end's motion"
    default_candidate = False
    differentiable = False  # the tangent model (engine/tangent.py) does not carry it
    parameters = (EffectParameter("tail_tether_N", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.tail_tether_N = values["tail_tether_N"]


class StribeckFriction(Effect):
    name = "stribeck_friction"
    summary = "lateral breakaway friction: mu_lat (1 + r exp(-(v/v_s)^2)) at low slip speed"
    parameters = (
        EffectParameter("stribeck_ratio", 0.0, 3.0, probe=0.5),
        EffectParameter("stribeck_speed_m_s", 1e-3, 0.2, fitted=False, default=0.01),
    )

    def configure(self, setup, values):
        setup.stribeck_ratio, setup.stribeck_speed_m_s = values["stribeck_ratio"], values["stribeck_speed_m_s"]


class WheelToe(Effect):
    name = "wheel_toe"
    summary = "every wheel's rolling direction yawed counter-clockwise from its module's axis"
    parameters = (EffectParameter("wheel_toe_deg", -10.0, 10.0, probe=1.0),)

    def configure(self, setup, values):
        setup.wheel_toe_rad = math.radians(values["wheel_toe_deg"])


class ModulePayload(Effect):
    name = "module_payload"
    summary = "an extra mass at one module's centre: its inertia, and its wheel's normal force"
    parameters = (
        EffectParameter("payload_kg", 0.0, 2.0, probe=0.3),
        EffectParameter("payload_module", 1, 14, fitted=False, default=7),
    )
    differentiable = False

    def configure(self, setup, values):
        module = values["payload_module"]
        if module != int(module):
            raise Rc1Error(f"effects.payload_module: must be a module number 1..14, got {module}")
        setup.payload_module, setup.payload_kg = int(module), values["payload_kg"]


class ServoLag(Effect):
    name = "servo_lag"
    summary = "a first-order servo response of time constant tau to the gait command"
    parameters = (EffectParameter("servo_lag_s", 0.0, 0.5, probe=0.05),)
    seen_in_replay = False  # replays drive the joints by their measured angles
    differentiable = False

    def gait(self, gait, values):
        """A first-order lag 1/(1 + tau s) of the serpenoid command A sin(omega t - phi) + B is, once its
        transient (a few tau) has passed, (A / sqrt(1 + (omega tau)^2)) sin(omega t - phi - atan(omega tau)) + B:
        the lagged command is again a serpenoid (Eqs. 3, 7), per joint."""
        from .gait import serpenoid_parameters

        tau = values["servo_lag_s"]
        if tau == 0.0:
            return gait
        amp, omega, phase, bias = serpenoid_parameters(gait)
        gain, delay = 1.0 / np.sqrt(1.0 + (omega * tau) ** 2), np.arctan(omega * tau)
        joints = [
            JointGait(
                joint=j + 1,
                amplitude_deg=math.degrees(amp[j] * gain[j]),
                frequency_deg_s=math.degrees(omega[j]),
                phase_deg=math.degrees(phase[j] + delay[j]),
                bias_deg=math.degrees(bias[j]),
            )
            for j in range(NUM_JOINTS)
        ]
        return dataclasses.replace(gait, joints=joints)


class PotentiometerFault(Effect):
    """A sensor fault of one joint's potentiometer (subclasses: how it misreads). RC1 records the servos' own
    potentiometers (paper section 2), so the fault sits either in the servo's loop (the servo drives the faulty
    reading to the command, so the joint moves off its command and the data show the command) or only in the data
    acquisition (its calibration: the joint follows the command and the data misread it, past the joint limit at
    the wave's peaks). A replay reads the measured angles back either way. One effect per joint, so that a
    diagnosis names the joint."""

    sensor = True
    differentiable = False  # it moves the gait command and the replay's reference, not the model's parameters
    kind = ""  # the effect's name is potentiometer_<kind>_j<joint>
    search = 0.0  # a diagnosis searches +-this much: what a calibration could have missed

    def __init__(self, joint: int, main: EffectParameter, summary: str):
        self.joint = joint
        self.name = f"potentiometer_{self.kind}_j{joint}"
        self.summary = summary
        # 1: in the servo's loop (the robot moves off its command); 0: in the acquisition only
        self.parameters = (main, EffectParameter(f"{self.name}_in_servo_loop", 0.0, 1.0, fitted=False, default=1.0))

    def coordinate_space(self):
        return [dataclasses.replace(self.main, lower=-self.search, upper=self.search)]

    def _in_loop(self, values) -> bool:
        key = self.parameters[1].key
        if values[key] not in (0.0, 1.0):
            raise Rc1Error(
                f"effects.{key}: must be 1 (the servo's loop) or 0 (the acquisition only), got {values[key]}"
            )
        return values[key] == 1.0

    def _with_joint(self, gait: Gait, **fields) -> Gait:
        """`gait` with this joint's own serpenoid terms replaced by `fields` (config.JointGait's)."""
        own = next((jg for jg in gait.joints if jg.joint == self.joint), JointGait(joint=self.joint))
        others = [jg for jg in gait.joints if jg.joint != self.joint]
        return dataclasses.replace(gait, joints=[*others, dataclasses.replace(own, **fields)])


class PotentiometerOffset(PotentiometerFault):
    """The potentiometer reads the angle plus a constant offset. In the servo's loop the joint settles at the
    command minus the offset (Eq. 7's bias B_i moved by -offset); a replay follows the readings minus the offset."""

    kind = "offset"
    search = 5.0  # deg

    def __init__(self, joint: int):
        super().__init__(
            joint,
            EffectParameter(f"potentiometer_offset_j{joint}_deg", -10.0, 10.0, probe=1.0),
            f"joint {joint}'s potentiometer reads the angle plus a constant offset (sensor fault)",
        )

    def configure_sensors(self, sensors, values):
        self._in_loop(values)
        sensors.angle_offsets_rad[self.joint - 1] += math.radians(values[self.main.key])

    def gait(self, gait, values):
        from .gait import serpenoid_parameters

        offset = values[self.main.key]
        if offset == 0.0 or not self._in_loop(values):
            return gait
        return self._with_joint(gait, bias_deg=math.degrees(serpenoid_parameters(gait)[3][self.joint - 1]) - offset)


class PotentiometerGain(PotentiometerFault):
    """The potentiometer reads the angle times (1 + a gain error), a calibration's slope missed as
    PotentiometerOffset's intercept can be. In the servo's loop the joint's amplitude and bias (Eq. 7) shrink by
    1 + error; a replay follows the readings divided by 1 + error."""

    kind = "gain"
    search = 0.1  # 10%

    def __init__(self, joint: int):
        super().__init__(
            joint,
            EffectParameter(f"potentiometer_gain_j{joint}_error", -0.5, 0.5, probe=0.02),
            f"joint {joint}'s potentiometer reads the angle times (1 + a gain error) (sensor fault)",
        )

    def configure_sensors(self, sensors, values):
        self._in_loop(values)
        sensors.angle_gains[self.joint - 1] *= 1.0 + values[self.main.key]

    def gait(self, gait, values):
        from .gait import serpenoid_parameters

        error = values[self.main.key]
        if error == 0.0 or not self._in_loop(values):
            return gait
        amplitude, _, _, bias = (math.degrees(v[self.joint - 1]) for v in serpenoid_parameters(gait))
        return self._with_joint(gait, amplitude_deg=amplitude / (1.0 + error), bias_deg=bias / (1.0 + error))


class CameraDelay(Effect):
    name = "camera_delay"
    summary = "the overhead camera's clock runs behind the robot's: a frame stamped t shows the head at t - delay"
    parameters = (EffectParameter("camera_delay_s", -0.5, 0.5, probe=0.05),)
    sensor = True
    differentiable = False  # it moves what the camera is predicted to see, not the run

    def configure_sensors(self, sensors, values):
        sensors.camera_delay_s += values["camera_delay_s"]


class ImuFault(Effect):
    name = "imu_fault"
    summary = "the head IMU reports (1 + scale error) x yaw rate + a bias common to every trial"
    parameters = (
        EffectParameter("imu_scale_error", -0.5, 0.5, probe=0.05),
        EffectParameter("imu_bias_rad_s", -0.5, 0.5, probe=0.02),
    )
    sensor = True
    differentiable = False

    def configure_sensors(self, sensors, values):
        sensors.imu_scale *= 1.0 + values["imu_scale_error"]
        sensors.imu_bias_rad_s += values["imu_bias_rad_s"]


class DiscrepancyTerm(Effect):
    """One term of the discrepancy model (discrepancy.py): a coefficient times a fixed shape, at the sites of one
    group or in the failed joints. Not a mechanism: what discovery (diagnose/discover.py) fits when the library's
    effects leave the data unexplained, named afterwards by its body, variable and sign."""

    discrepancy = True
    default_candidate = False
    BOUNDS = {"N_s_per_m": 5.0, "N": 5.0, "Nm": 1.0, "Nm_per_rad": 5.0, "Nm_s_per_rad": 0.5}

    def __init__(self, index: int, group: str, kind: str, unit: str, words: str):
        self.index, self.group, self.kind, self.unit, self.words = index, group, kind, unit, words
        self.name = f"discrepancy_{group}_{kind}"
        where = "each failed joint" if group == "failed_joint" else f"the {group}'s sites"
        self.summary = f"discrepancy term: {words} at {where}"
        self.failed_joints_only = group == "failed_joint"
        bound = self.BOUNDS[unit]
        self.parameters = (EffectParameter(f"{self.name}_{unit}", self._lower(bound), bound, probe=0.1 * bound),)

    def _lower(self, bound: float) -> float:
        """A term that resists motion may take away at most the paper's own friction where it acts: none at the
        wheelless head, the tail's end or in a failed joint's dry friction, c_lat / c_long at a wheel (its Coulomb
        part, which needs the wheel's load, is bounded as the other terms), c_joint in a failed joint."""
        if not self.kind.startswith(("drag", "dry")):
            return -bound
        paper = Friction()
        if self.group == "failed_joint":
            return -paper.c_joint if self.kind == "drag" else 0.0
        if self.group in ("head", "tail"):
            return 0.0
        return {"drag_lat": -paper.c_lat, "drag_long": -paper.c_long}.get(self.kind, -bound)

    def configure(self, setup, values):
        setup.discrepancy[self.index] = values[self.main.key]


LIBRARY: dict[str, Effect] = {}


def register(effect: Effect) -> Effect:
    """Add an effect to the library (a user's own, for instance); its parameter keys must be new."""
    taken = {p.key for e in LIBRARY.values() for p in e.parameters if e.name != effect.name}
    for p in effect.parameters:
        if p.key in taken:
            raise ValueError(f"effect {effect.name}: parameter key {p.key} is already used")
    LIBRARY[effect.name] = effect
    return effect


for _effect in (
    GroundSlope(),
    LateralFrictionAsymmetry(),
    LongitudinalFrictionAsymmetry(),
    HeadDrag(),
    JointCoulombFriction(),
    CompliantStop(),
    HeadCantilever(),
    TailTether(),
    StribeckFriction(),
    WheelToe(),
    ModulePayload(),
    ServoLag(),
    *(PotentiometerOffset(j) for j in range(1, NUM_JOINTS + 1)),
    *(PotentiometerGain(j) for j in range(1, NUM_JOINTS + 1)),
    CameraDelay(),
    ImuFault(),
    *(DiscrepancyTerm(i, *term) for i, term in enumerate(term_names())),
):
    register(_effect)


# Names that stand for a group of the library in a list of candidates (diagnose, rc1 diagnose --candidates).
CANDIDATE_GROUPS = {
    "physical": lambda e: not e.sensor and e.default_candidate,
    "sensor": lambda e: e.sensor,
    "study": lambda e: not e.default_candidate and not e.discrepancy,  # issue 41's mechanisms (docs/paper.md)
    "discrepancy": lambda e: e.discrepancy,  # the discrepancy model's terms (discrepancy.py), for discovery
}


def candidate_names(names: list[str] | None = None) -> list[str]:
    """Effect names, with the groups expanded; by default the physical effects. The sensor faults are asked for
    (`sensor`): from the motion alone a bend at one joint mimics a toe or a failed joint's dry friction
    (docs/findings.md), so on by default they would blur what the physics tells."""
    out = []
    for name in names or ["physical"]:
        if name in CANDIDATE_GROUPS:
            out += [e.name for e in LIBRARY.values() if CANDIDATE_GROUPS[name](e)]
        elif name in LIBRARY:
            out.append(name)
        else:
            raise ValueError(
                f"unknown effect '{name}' (known: {', '.join(LIBRARY)}; groups: {', '.join(CANDIDATE_GROUPS)})"
            )
    return list(dict.fromkeys(out))


def potentiometer_faults(joints) -> list[str]:
    """The sensor-fault candidates of these joints' potentiometers (1-based joint numbers)."""
    return [e.name for e in LIBRARY.values() if isinstance(e, PotentiometerFault) and e.joint in set(joints)]


def parameter_owner(key: str) -> Effect | None:
    return next((e for e in LIBRARY.values() if any(p.key == key for p in e.parameters)), None)


def parameter(key: str) -> EffectParameter | None:
    """The effect parameter with this key, or None."""
    return next((p for e in LIBRARY.values() for p in e.parameters if p.key == key), None)


def effect_values(effects: dict[str, float], effect: Effect) -> dict[str, float]:
    return {p.key: float(effects.get(p.key, p.default)) for p in effect.parameters}


def active(effects: dict[str, float]) -> list[Effect]:
    """The effects whose parameters `effects` sets (in library order)."""
    return [e for e in LIBRARY.values() if any(p.key in effects for p in e.parameters)]


def validate_effects(effects: dict[str, float], *, where: str) -> None:
    """Rc1Error naming the first unknown key or out-of-range value."""
    for key, value in effects.items():
        p = parameter(key)
        if p is None:
            known = ", ".join(p.key for e in LIBRARY.values() for p in e.parameters)
            raise Rc1Error(f"{where}: effects.{key}: unknown effect parameter (known: {known})")
        if value is None or not math.isfinite(value) or not p.lower <= value <= p.upper:
            raise Rc1Error(f"{where}: effects.{key}: must be a number in [{p.lower:g}, {p.upper:g}], got {value}")


def parse_effect(text: str) -> tuple:
    """`NAME=VALUE` (an effect's main parameter) or `KEY=VALUE` (any parameter) -> (key, value)."""
    name, sep, value = text.partition("=")
    effect = LIBRARY.get(name)
    key = effect.main.key if effect is not None else name
    if parameter(key) is None:
        raise ValueError(f"unknown effect '{name}' (known: {', '.join(LIBRARY)}, or a parameter key)")
    if not sep:
        raise ValueError(f"effect '{name}' needs a value: {name}=VALUE")
    try:
        return key, float(value)
    except ValueError:
        raise ValueError(f"effect '{name}': '{value}' is not a number") from None


def coordinate_owner(name: str) -> Effect | None:
    """The effect with a fitted parameter or a diagnosis coordinate called `name`, or None."""
    return next((e for e in LIBRARY.values() if any(p.key == name for p in (*e.fitted(), *e.coordinate_space()))), None)


def shifted(effects: dict[str, float], name: str, delta: float) -> dict[str, float]:
    """`effects` with the fitted parameter or coordinate `name` (coordinate_owner) moved by `delta`."""
    effect = coordinate_owner(name)
    if effect is None:
        raise ValueError(f"no effect parameter or coordinate '{name}'")
    values = effect_values(effects, effect)
    if name in values:
        return {**effects, name: values[name] + delta}
    coordinates = effect.coordinates(values)
    coordinates[name] += delta
    return {**effects, **effect.from_coordinates(coordinates)}


def commanded_gait(gait: Gait, effects: dict[str, float]) -> Gait:
    """The gait as the joints receive it, after the effects that act on the command (servo_lag)."""
    for effect in active(effects):
        gait = effect.gait(gait, effect_values(effects, effect))
    return gait


def sensor_model(effects: dict[str, float]) -> SensorModel:
    """The sensors as the active sensor faults make them."""
    sensors = SensorModel(angle_offsets_rad=np.zeros(NUM_JOINTS))
    for effect in active(effects):
        effect.configure_sensors(sensors, effect_values(effects, effect))
    return sensors


def model_setup(effects: dict[str, float]) -> ModelSetup:
    setup = ModelSetup(gravity=np.array([0.0, 0.0, -GRAVITY_M_S2]))
    for effect in active(effects):
        effect.configure(setup, effect_values(effects, effect))
    return setup


def apply_effects(built, context, effects: dict[str, float], *, friction, sgn_smoothing_m_s: float) -> ModelSetup:
    """Write the friction and the effects into `context` (after SetDefaultContext): gravity, payload, the
    friction parameters (friction.friction_parameters: coefficients, friction-law terms, normal forces,
    wheel toe), explicit forces. Every run calls it, so nothing of a previous run's effects stays."""
    from .friction import KnownForces, friction_parameters
    from .model import set_payload

    setup = model_setup(effects)
    plant, system = built.plant, built.friction
    plant.mutable_gravity_field().set_gravity_vector(setup.gravity)  # the plant's, shared by its contexts
    set_payload(plant, plant.GetMyMutableContextFromRoot(context), setup.payload_module, setup.payload_kg)
    system.parameters(system.GetMyMutableContextFromRoot(context))[:] = friction_parameters(
        friction=friction, sgn_smoothing_m_s=sgn_smoothing_m_s, setup=setup, geometry=built.rc1.geometry
    )
    known = KnownForces(tuple(setup.extra_forces), bool(setup.gravity[0] or setup.gravity[1]))
    system.set_known_forces(system.GetMyMutableContextFromRoot(context), known)
    return setup
