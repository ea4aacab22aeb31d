"""What a user types, loaded and checked: named scenarios (YAML, read with Drake's yaml_load_typed),
model files, and the validation every scenario passes before a run (scenario keys, then rc1_drake/effects'
parameter bounds). Errors are one line naming the file or source, the key and the problem.
"""

import dataclasses
import math
from pathlib import Path

from pydrake.common.yaml import yaml_load_typed

from .config import FAILURE_MODES, FRICTION_NAMES, NUM_JOINTS, REPO_ROOT, Friction, Rc1Error, Scenario, Servo
from .effects import validate_effects

DEFAULT_SCENARIOS = REPO_ROOT / "scenarios" / "rc1.yaml"


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
    """What a fit or a diagnosis found: friction coefficients and physical effects (rc1_drake/effects/); read by
    `--model-file` of run, compare, sweep and identify. A file holding only the five friction
    coefficients at the top level (the older friction file) is read too."""

    friction: Friction = dataclasses.field(default_factory=Friction)
    effects: dict[str, float] = dataclasses.field(default_factory=dict)
    servo: Servo | None = None  # the working joints' servos, where the model names them (None: each command's own)


def load_model_file(path) -> ModelFile:
    """The model file at `path`, validated; Rc1Error names the file and the problem. `FILE:NAME` takes the model of
    scenario NAME of a file of named scenarios (its friction, effects and servos); such a file without a name is
    refused, naming its scenarios."""
    import yaml

    path, name = _named(Path(path))
    if not path.is_file():
        raise Rc1Error(f"{path}: no such model file")
    try:
        top = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as e:
        raise Rc1Error(f"{path}: not valid YAML: {_one_line(e)}") from None
    scenarios = isinstance(top, dict) and bool(top) and not set(top) & {f.name for f in dataclasses.fields(ModelFile)}
    scenarios = scenarios and not set(top) <= set(FRICTION_NAMES) and all(isinstance(v, dict) for v in top.values())
    if name is not None or scenarios:
        if not scenarios:
            raise Rc1Error(f"{path}: a model file, not a file of named scenarios: give it without ':{name}'")
        if name is None:
            raise Rc1Error(
                f"{path}: a file of named scenarios ({', '.join(top)}), not a model file: name one, e.g. "
                f"{path}:{next(iter(top))}"
            )
        scenario = load_scenario(name, filename=path)
        return ModelFile(friction=scenario.friction, effects=dict(scenario.effects), servo=scenario.servo)
    flat = isinstance(top, dict) and bool(top) and set(top) <= set(FRICTION_NAMES)
    try:
        model = (
            ModelFile(friction=yaml_load_typed(schema=Friction, filename=str(path)))
            if flat
            else yaml_load_typed(schema=ModelFile, filename=str(path))
        )
    except Exception as e:  # noqa: BLE001 - any parse failure is a malformed file, reported in one line
        raise Rc1Error(f"{path}: {_one_line(e) or type(e).__name__}") from None
    validate(Scenario(friction=model.friction, effects=model.effects), where=str(path))
    return model


def _named(path: Path) -> tuple:
    """(the file, the scenario's name or None) of `path`, FILE or FILE:NAME."""
    file, colon, name = str(path).rpartition(":")
    if colon and name and not path.is_file() and Path(file).is_file():
        return Path(file), name
    return path, None


def model_to_yaml(friction: Friction, effects: dict[str, float] | None = None, *, comment: str = "") -> str:
    lines = [
        f"# {comment or 'Model file'}: friction (rc1_drake.config.Friction) and effects (rc1 effects);",
        "# read with --model-file.",
        "friction:",
    ]
    lines += [f"  {name}: {getattr(friction, name):.6g}" for name in FRICTION_NAMES]
    lines += ["effects:" + ("" if effects else " {}")]
    lines += [f"  {key}: {value:.6g}" for key, value in (effects or {}).items()]
    return "\n".join(lines) + "\n"


def list_scenarios(filename=DEFAULT_SCENARIOS) -> list[str]:
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
