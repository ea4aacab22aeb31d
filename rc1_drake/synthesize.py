"""Synthetic experiments: campaigns in the measurement format, made by a known truth model.

The truth is the Drake model driven by the gait (servos, failures), with chosen friction, optional
extra physical effects, trial-to-trial variation (start phase and pose) and sensor noise
(potentiometers, head IMU, overhead camera, the hand-measured final position). Everything random
comes from one seed.
"""

import collections
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from .config import (
    NUM_JOINTS,
    TRUTH_MODELS,
    Failure,
    Friction,
    Gait,
    Numerics,
    Rc1Error,
    Scenario,
    Servo,
    Start,
    Stop,
)
from .diagram import build_key
from .effects import LIBRARY, commanded_gait, sensor_model
from .engine import make_session
from .measurements import Campaign, Trial, write_trial
from .measurements import Stop as TrialStop


@dataclasses.dataclass
class Case:
    failed_joints: list[int]
    trials: int
    bias_deg: float = 0.0
    gait: Gait | None = None  # the commanded gait (its bias replaced by bias_deg); None: the paper's
    seconds: float | None = None  # its trials end after this long (no line, no turns); None: the campaign's stop


@dataclasses.dataclass
class Noise:
    """Standard deviations of the sensors (and camera dropouts); scale them all with `scaled`."""

    potentiometer_deg: float = 0.25
    imu_rad_s: float = 0.02
    imu_bias_rad_s: float = 0.01  # per trial, constant
    camera_m: float = 0.005
    camera_yaw_deg: float = 0.5
    camera_dropout: float = 0.05  # fraction of samples where the camera misses the head
    hand_m: float = 0.01  # the final position, measured by hand

    def scaled(self, factor: float) -> "Noise":
        return dataclasses.replace(
            self,
            **{f.name: getattr(self, f.name) * factor for f in dataclasses.fields(self) if f.name != "camera_dropout"},
        )


@dataclasses.dataclass
class Variation:
    """Trial-to-trial variation of the start (standard deviations)."""

    phase_deg: float = 5.0
    position_m: float = 0.01
    heading_deg: float = 1.0


# The paper's campaign (section 4, Table 2) plus one joint-2 trial. The bias straightens a joint-7
# failure in this model (docs/sweeps.md).
PAPER_DESIGN = [Case([], 5), Case([7], 5), Case([13], 5), Case([7], 5, bias_deg=-0.9), Case([2], 1)]

# The richest design within RC1's servos (joint speed A omega <= 140 deg/s) whose trials replay
# faithfully (benchmarks/identification.py, docs/identification.md): three gait frequencies
# spread the rolling speeds (mu_long against c_long); failures of joints 7 and 13 at two speeds show
# c_joint. (Joint-2 failures circle, and their replays drift from the truth even at its coefficients.)
IDENTIFICATION_DESIGN = [
    Case([], 1),
    Case([], 1, gait=Gait(frequency_deg_s=70.0)),
    Case([], 1, gait=Gait(frequency_deg_s=210.0)),
    Case([7], 1),
    Case([7], 1, gait=Gait(frequency_deg_s=210.0)),
    Case([13], 1),
]
SERVO_SPEED_LIMIT_DEG_S = 140.0  # HiTec HS5645MG (paper section 2; models/rc1.sdf)
DESIGNS = {"paper": PAPER_DESIGN, "identification": IDENTIFICATION_DESIGN}


# What the independent model can express: the wheel toe, the sensor faults (they act on its command and on what its
# sensors read, not on its physics), the tail's tether and the discrepancy terms (reference.HiddenForces).
# A floor seam (reference.HiddenForces) is in no other model, nor in the library: what discovery makes of a shape
# it has no term for; the failed joints' stop beyond the limit, of another gain and damping, is another form of
# failed joint (issue 67).
# The lab's forms (LabForms) are other sensors than the replay assumes.
REFERENCE_ONLY = (
    "floor_seam_Nm", "floor_seam_x_m", "reference_stop_Nm_per_rad", "reference_stop_Nm_s_per_rad",
    "reference_linkage_rad_per_Nm", "reference_potentiometer_step_deg", "reference_camera_marker_m",
    "reference_camera_scale_error",
)  # fmt: skip
REFERENCE_EFFECTS = (
    "wheel_toe_deg",
    "linkage_compliance_rad_per_Nm",  # its joints follow their command: the potentiometers' lead alone
    "tail_tether_N",
    *(e.main.key for e in LIBRARY.values() if e.sensor or e.discrepancy),
    *REFERENCE_ONLY,
)


@dataclasses.dataclass(frozen=True)
class LabForms:
    """How another lab's sensors differ in form from what the replay assumes (issue 67; reference truth only).

    linkage: each potentiometer reads its servo's shaft, a compliant four-bar away from the module, so the reading
    leads the joint's angle by the compliance times the torque the servo gives it (rad per N m). potentiometer_step:
    the readings are quantized by the acquisition's converter (deg). camera_marker: the camera tracks a marker this
    far ahead of the head's centre along its axis (m); camera_scale_error: its floor calibration scales positions
    about the floor's origin by 1 + this. The trial's initial pose is the camera's (before the robot moves); the
    hand-measured final position has neither."""

    linkage_rad_per_Nm: float = 0.0
    potentiometer_step_deg: float = 0.0
    camera_marker_m: float = 0.0
    camera_scale_error: float = 0.0

    @classmethod
    def from_effects(cls, effects: dict) -> "LabForms":
        out = cls(**{f.name: float(effects.get(f"reference_{f.name}", 0.0)) for f in dataclasses.fields(cls)})
        for f, (low, high) in zip(dataclasses.fields(cls), ((0, 0.2), (0, 2.0), (-0.1, 0.1), (-0.1, 0.1)), strict=True):
            if not low <= getattr(out, f.name) <= high:
                raise Rc1Error(
                    f"synthesize: effects.reference_{f.name}: must lie in [{low}, {high}], got {getattr(out, f.name)}"
                )
        return out

    def camera(self, pose: np.ndarray) -> np.ndarray:
        """The camera's (x, y, yaw) of the head's true `pose` (N, 3)."""
        xy = pose[:, :2] + self.camera_marker_m * np.column_stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])])
        return np.column_stack([xy * (1.0 + self.camera_scale_error), pose[:, 2]])

    def quantized(self, readings: np.ndarray) -> np.ndarray:
        step = math.radians(self.potentiometer_step_deg)
        return readings if step == 0.0 else step * np.round(readings / step)


def synthesize_campaign(
    folder,
    *,
    design=PAPER_DESIGN,
    friction=None,
    effects=None,
    noise=None,
    variation=None,
    seed=0,
    camera=True,
    stop=None,
    sample_period_s=0.01,
    numerics=None,
    truth_file=None,
    name=None,
    truth_model="drake",
    record_after_s=0.0,
) -> Campaign:
    """Write a campaign to `folder` and, if `truth_file` is given, what made it. Unset arguments take
    their defaults: the paper's friction, no effect, Noise(), Variation(), Stop(). `effects` maps
    effect parameter keys to values (rc1_drake/effects/).

    truth_model "drake": the Drake model driven by the gait through its servos, from the protocol's start;
    "reference": the independent planar model of reference.py (kinematic joints as the paper drives them,
    its own joint-limit model, the head at rest at its start), a model this project's replay was not made
    from. record_after_s: the recording starts that long after the robot did (the data then start in motion)."""
    if truth_model not in TRUTH_MODELS:
        raise Rc1Error(f"synthesize: truth model must be one of {', '.join(TRUTH_MODELS)}, got {truth_model!r}")
    if truth_model == "reference" and (beyond := sorted(set(effects or {}) - set(REFERENCE_EFFECTS))):
        raise Rc1Error(
            f"synthesize: the reference truth model can express wheel_toe_deg, tail_tether_N, "
            "linkage_compliance_rad_per_Nm, the sensor faults, "
            f"the discrepancy terms (rc1 effects) and a floor seam only, not {', '.join(beyond)}"
        )
    if truth_model == "drake" and (only := sorted(set(effects or {}) & set(REFERENCE_ONLY))):
        raise Rc1Error(
            f"synthesize: {', '.join(only)}: only the reference truth model reads these (a floor seam, its own "
            "failed-joint stop, its lab's forms)"
        )
    if truth_model == "reference":  # its own forces checked where they are read, before any trial is made
        from .reference import HiddenForces

        try:
            HiddenForces.from_effects(effects or {})
        except ValueError as e:
            raise Rc1Error(f"synthesize: {e}") from None
        LabForms.from_effects(effects or {})
    if record_after_s < 0 or abs(record_after_s / sample_period_s - round(record_after_s / sample_period_s)) > 1e-9:
        raise Rc1Error(
            f"synthesize: record_after_s must be a non-negative multiple of the sample period, got {record_after_s}"
        )
    friction, effects = friction or Friction(), dict(effects or {})
    noise, variation, stop = noise or Noise(), variation or Variation(), stop or Stop()
    rng = np.random.default_rng(seed)
    numerics = dataclasses.replace(numerics or Numerics(), log_period_s=sample_period_s)
    folder = Path(folder)
    trials, sessions, numbered = [], {}, collections.Counter()
    for case in design:
        _check_within_servos(case)
    for case in design:
        label = (
            ("j" + "_".join(map(str, case.failed_joints)) if case.failed_joints else "nominal")
            + ("_bias" if case.bias_deg else "")
            + (f"_f{case.gait.frequency_deg_s:g}_p{case.gait.phase_step_deg:g}" if case.gait else "")
        )
        for _ in range(case.trials):
            numbered[label] += 1  # cases sharing a label (a bias each way) number on: no trial overwrites another
            scenario = Scenario(
                gait=dataclasses.replace(
                    case.gait or Gait(),
                    bias_deg=case.bias_deg,
                    phase_offset_deg=float(rng.normal(0, variation.phase_deg)),
                ),
                friction=friction,
                effects=effects,
                failures=[Failure(joint=j) for j in case.failed_joints],
                start=Start(
                    x_m=float(rng.normal(0, variation.position_m)),
                    y_m=float(rng.normal(0, variation.position_m)),
                    heading_deg=float(rng.normal(0, variation.heading_deg)),
                ),
                stop=stop if case.seconds is None else Stop(line_x_m=None, revolutions=None, time_limit_s=case.seconds),
                numerics=numerics,
            )
            if truth_model == "reference":
                run, scenario = _reference_run(scenario, record_after_s, sample_period_s)
            else:
                run, scenario = _drake_run(scenario, record_after_s, sessions)
            on_grid = np.abs(run.t / sample_period_s - np.round(run.t / sample_period_s)) < 1e-6  # not the stop
            trial = _measure(run, scenario, f"{label}_{numbered[label]}", noise, rng, camera, run.t[on_grid])
            write_trial(folder, trial.trial_id, trial)
            trials.append(trial)
    if truth_file is not None:
        truth = {
            "campaign": str(name or folder.name),
            "seed": seed,
            "friction": dataclasses.asdict(friction),
            "effects": effects,
            "noise": dataclasses.asdict(noise),
            "variation": dataclasses.asdict(variation),
            "design": [dataclasses.asdict(c) for c in design],
            "numerics": dataclasses.asdict(numerics),
            "truth_model": truth_model,
            "record_after_s": record_after_s,
        }
        Path(truth_file).write_text(json.dumps(truth, indent=2) + "\n")
    return Campaign(path=folder, trials=trials)


def _recorded(scenario: Scenario, record_after_s: float) -> Scenario:
    """The scenario as the trial records it when the recording starts record_after_s into the motion: the
    gait's wave advanced by that time (Eq. 3: omega (t + t_r) - phi)."""
    gait = scenario.gait
    offset = (gait.phase_offset_deg + gait.frequency_deg_s * record_after_s + 180.0) % 360.0 - 180.0
    return dataclasses.replace(scenario, gait=dataclasses.replace(gait, phase_offset_deg=offset))


def _late(scenario: Scenario, record_after_s: float) -> Scenario:
    return dataclasses.replace(
        scenario, stop=dataclasses.replace(scenario.stop, time_limit_s=scenario.stop.time_limit_s + record_after_s)
    )


def _drake_run(scenario: Scenario, record_after_s: float, sessions: dict) -> tuple:
    """The Drake truth's run, from the recording's start, and the scenario the trial records."""
    late = _late(scenario, record_after_s)
    key = build_key(late)
    if key not in sessions:
        sessions[key] = make_session(late)
    run = sessions[key].simulate(late)
    keep = run.t >= record_after_s - 1e-9
    run = dataclasses.replace(
        run, t=run.t[keep] - record_after_s, state=run.state[keep], servo_torque=run.servo_torque[keep]
    )
    return run, _recorded(scenario, record_after_s)


def _reference_run(scenario: Scenario, record_after_s: float, period: float) -> tuple:
    """The reference truth's run (reference.simulate_reference from the head at rest, sampled every `period`
    from the recording's start), as a Run, and the scenario the trial records."""
    from .engine.dynamics import plant_numbers
    from .protocol import Run
    from .reference import simulate_reference

    late = _late(scenario, record_after_s)
    late = dataclasses.replace(late, gait=commanded_gait(late.gait, late.effects))  # a sensor fault's command
    end = late.stop.time_limit_s
    grid = record_after_s + np.arange(int(math.floor((end - record_after_s) / period + 1e-9)) + 1) * period
    geometry = plant_numbers().geometry
    ref = simulate_reference(
        late, geometry, at_rest="head", t_eval=grid, toe_rad=math.radians(scenario.effects.get("wheel_toe_deg", 0.0))
    )
    keep = ref.t >= record_after_s - 1e-9
    z = np.column_stack([ref.head_xy, ref.head_yaw, ref.q])
    state = np.hstack([z, ref.z_dot])[keep]
    reason = "crossed" if ref.crossed else "circling" if ref.circled else "timed_out"
    run = Run(
        scenario=scenario,
        t=ref.t[keep] - record_after_s,
        state=state,
        servo_torque=ref.joint_torque[keep],
        stop_reason=reason,
        wall_time_s=ref.wall_time_s,
        geometry=geometry,
    )
    return run, _recorded(scenario, record_after_s)


def noise_free_twin(trial: Trial, *, friction: Friction, effects=None, servo: Servo | None = None) -> Trial:
    """`trial` as the model (friction, effects; its servos `servo`, default Servo()) makes it with no sensor noise,
    driven by the servos: the trial's
    gait, failures, start pose, stop rule and sample times, with a camera. Its run goes through the stop event to
    the replay's time limit (replay.replay_scenario) and its final position follows the replays' rule (the head's
    at the event, or at that limit if none comes), so that a replay of the twin has the trial's residual entries
    and shows what the replay itself misses on this kind of motion (sysid.input_noise.replay_error)."""
    from .gait import serpenoid
    from .kinematics import module_yaws
    from .replay import replay_scenario

    effects = dict(effects or {})
    q0, _ = serpenoid(0.0, commanded_gait(trial.gait, effects))
    x, y, head_yaw = (float(v) for v in trial.initial_head_pose)
    scenario = Scenario(
        gait=trial.gait,
        servo=servo or Servo(),
        friction=friction,
        effects=effects,
        failures=[Failure(joint=j) for j in trial.failed_joints],
        start=Start(x_m=x, y_m=y, heading_deg=math.degrees(head_yaw + module_yaws(0.0, q0).mean())),
        stop=replay_scenario(trial, friction, effects).stop,  # through its event, as the replays
        numerics=Numerics(log_period_s=0.0),  # every update: the trial's own sample times are interpolated
    )
    run = make_session(scenario).simulate(scenario)
    silent = dataclasses.replace(Noise().scaled(0.0), camera_dropout=0.0)
    twin = _measure(run, scenario, trial.trial_id, silent, np.random.default_rng(0), True, trial.t - trial.t[0])
    return dataclasses.replace(
        twin,
        stop=trial.stop,
        final_head_xy=run.final_head_xy.copy(),  # the head itself, not what a camera with a fault would show of it
        initial_head_rates=run.state[0, 16:19].copy(),  # its start, known exactly
        notes=f"noise-free twin of {trial.trial_id}",
    )


def _check_within_servos(case: Case) -> None:
    """Rc1Error for a gait RC1's servos cannot drive: the truth model does not cap joint speed."""
    from .gait import serpenoid_parameters

    amp, omega, _, _ = serpenoid_parameters(case.gait or Gait())
    peak = math.degrees(float(np.max(np.abs(amp) * omega)))
    if peak > SERVO_SPEED_LIMIT_DEG_S + 1e-9:
        raise Rc1Error(
            f"synthesize: case {case}: the gait needs {peak:.0f} deg/s of joint speed; RC1's servos "
            f"reach {SERVO_SPEED_LIMIT_DEG_S:.0f} deg/s"
        )


def _measure(run, scenario, trial_id, noise: Noise, rng, camera, t) -> Trial:
    """What the robot's sensors and the experimenter would have recorded of `run` at the sample times `t` (s)."""
    n = len(t)
    sensors = sensor_model(scenario.effects)  # the sensor faults, before the noise
    lab = LabForms.from_effects(scenario.effects)
    shafts = run.q + (lab.linkage_rad_per_Nm + sensors.linkage_rad_per_Nm) * run.servo_torque
    angles = np.column_stack([np.interp(t, run.t, shafts[:, j]) for j in range(NUM_JOINTS)])
    q = lab.quantized(sensors.potentiometers(angles) + rng.normal(0, math.radians(noise.potentiometer_deg), (n, 13)))
    for f in scenario.failures:
        q[:, f.joint - 1] = np.nan
    rate = (
        sensors.imu(t, run.t, run.head_yaw_rate)
        + rng.normal(0, noise.imu_bias_rad_s)
        + rng.normal(0, noise.imu_rad_s, n)
    )
    cam = None
    if camera:
        pose = sensors.camera(t, run.t, lab.camera(run.state[:, :3]))
        cam = np.column_stack(
            [
                pose[:, :2] + rng.normal(0, noise.camera_m, (n, 2)),
                pose[:, 2] + rng.normal(0, math.radians(noise.camera_yaw_deg), n),
            ]
        )
        cam[rng.random(n) < noise.camera_dropout] = np.nan
    if run.stop_reason == "crossed":
        stop = TrialStop("line", scenario.stop.line_x_m)
    elif run.stop_reason == "circling":
        stop = TrialStop("revolutions", scenario.stop.revolutions)
    else:
        stop = TrialStop("time", scenario.stop.time_limit_s)
    return Trial(
        trial_id=trial_id,
        failed_joints=scenario.failed_joints,
        gait=dataclasses.replace(scenario.gait, joints=[]),
        stop=stop,
        initial_head_pose=lab.camera(run.state[:1, :3])[0],  # where the lab's camera put the head before it moved
        final_head_xy=run.final_head_xy + rng.normal(0, noise.hand_m, 2),
        t=t,
        q=q,
        head_yaw_rate=rate,
        camera=cam,
        notes="synthetic (rc1 synthesize)",
    )
