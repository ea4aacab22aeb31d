"""The effect's types: an Effect names a mechanism and its parameters (EffectParameter) and says how it changes the
model (ModelSetup: gravity, payload, friction-law terms, toe, explicit forces), the gait command, or what the sensors
report (SensorModel)."""

import dataclasses
from collections.abc import Callable

import numpy as np

from ..config import NUM_JOINTS, Gait, Servo
from ..discrepancy import NUM_TERMS


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
    # The potentiometers sit on the servos' shafts, a compliant linkage away from the joints: a shaft leads its
    # joint by this compliance times the torque its servo gives (effects.physical.ServoLinkage), rad per N m.
    linkage_rad_per_Nm: float = 0.0

    def potentiometers(self, q) -> np.ndarray:
        """What the potentiometers read of joint (or shaft) angles q (..., 13), rad."""
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

    def servo(self, servo: Servo, values: dict[str, float]) -> Servo:
        """The servo as the joints feel it (a compliant linkage in series with it)."""
        return servo

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
