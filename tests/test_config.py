"""Scenario files: named scenarios load; bad input is one line naming the file, key and problem."""

import pytest

from rc1_drake.config import REPO_ROOT, Rc1Error
from rc1_drake.scenarios import DEFAULT_SCENARIOS, list_scenarios, load_scenario


def test_shipped_scenarios_load():
    names = list_scenarios()
    assert {"nominal", "joint_2", "joint_7", "joint_13", "joint_7_bias", "isotropic"} <= set(names)
    for name in names:
        load_scenario(name)
    assert load_scenario("joint_7").failed_joints == [7]


def test_the_paper_findings_scenarios_share_one_model_with_proportional_servos():
    path = REPO_ROOT / "scenarios" / "paper_findings.yaml"
    scenarios = {name: load_scenario(name, filename=path) for name in list_scenarios(path)}
    assert {"nominal", "joint_2", "joint_7", "joint_13"} <= set(scenarios)
    models = {(repr(s.servo), repr(s.friction), tuple(sorted(s.effects.items()))) for s in scenarios.values()}
    assert len(models) == 1  # one model: the cases differ only in their failures
    joint_2 = scenarios["joint_2"]
    assert joint_2.servo.ki_Nm_per_rad_s == 0.0 < joint_2.servo.kp_Nm_per_rad and joint_2.failed_joints == [2]
    assert joint_2.effects["head_on_wheel2"] > 0  # the head carried on module 2's wheels


@pytest.mark.parametrize(
    "text, expected",
    [
        ("s:\n  friction: {mu_lat: -1}\n", "friction.mu_lat: must be >= 0"),
        ("s:\n  failures: [{joint: 14}]\n", "failures[0].joint: must be 1..13"),
        ("s:\n  failures: [{joint: 3, mode: exploded}]\n", "failures[0].mode: unknown mode 'exploded'"),
        ("s:\n  gait: {amplitude: 30}\n", "amplitude"),
        ("s:\n  gait: {amplitude_deg: abc}\n", "abc"),
        ("s:\n  numerics: {time_step_s: 0.5}\n", "numerics.time_step_s"),
        ("s:\n  stop: {line_x_m: -1}\n", "stop.line_x_m"),
        ("s:\n  servo: {lead_s: -0.001}\n", "servo.lead_s: must be >= 0"),
        ("s: [1, 2\n", "not valid YAML"),
    ],
)
def test_bad_scenarios_give_one_line_errors(tmp_path, text, expected):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(Rc1Error) as err:
        load_scenario("s", filename=path)
    message = str(err.value)
    assert "\n" not in message and str(path) in message and expected in message


def test_unknown_scenario_and_missing_file(tmp_path):
    with pytest.raises(Rc1Error, match="no scenario named 'nope'"):
        load_scenario("nope")
    with pytest.raises(Rc1Error, match="no such scenario file"):
        load_scenario("nominal", filename=tmp_path / "missing.yaml")
    assert DEFAULT_SCENARIOS.is_file()


def test_a_model_is_taken_by_name_from_a_file_of_named_scenarios(tmp_path):
    """--model-file FILE:NAME (issue 69): the scenario's friction, effects and servos; the file alone, or a name
    it lacks, is one line naming its scenarios; a model file given a name is refused."""
    from rc1_drake.scenarios import load_model_file

    path = REPO_ROOT / "scenarios" / "paper_findings.yaml"
    model = load_model_file(f"{path}:joint_2")
    scenario = load_scenario("joint_2", filename=path)
    assert model.friction == scenario.friction and model.effects == scenario.effects
    assert model.servo == scenario.servo and model.servo.ki_Nm_per_rad_s == 0.0
    with pytest.raises(Rc1Error, match=r"a file of named scenarios \(nominal, joint_2, .*\), not a model file: name"):
        load_model_file(path)
    with pytest.raises(Rc1Error, match="no scenario named 'nope' \\(known: nominal, joint_2"):
        load_model_file(f"{path}:nope")
    plain = tmp_path / "m.yaml"
    plain.write_text("friction: {mu_lat: 2.0}\neffects: {}\n")
    assert load_model_file(plain).friction.mu_lat == 2.0 and load_model_file(plain).servo is None
    with pytest.raises(Rc1Error, match="a model file, not a file of named scenarios: give it without ':x'"):
        load_model_file(f"{plain}:x")


def test_every_subpackage_is_installed():
    """pyproject's explicit package list names every folder of rc1_drake with an __init__.py (a package left out
    imports from a checkout and is missing from an installed wheel)."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(root).parts) for p in (root / "rc1_drake").rglob("__init__.py")}
    assert found == listed, (found - listed, listed - found)
