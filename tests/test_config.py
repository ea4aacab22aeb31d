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


def test_paper_findings_scenarios_carry_the_p_only_servo_and_the_cantilever():
    path = REPO_ROOT / "scenarios" / "paper_findings.yaml"
    assert {"nominal", "joint_2", "joint_7", "joint_13"} <= set(list_scenarios(path))
    for name in list_scenarios(path):
        s = load_scenario(name, filename=path)
        assert (s.servo.kp_Nm_per_rad, s.servo.ki_Nm_per_rad_s) == (5.0, 0.0) and s.effects == {"head_on_wheel2": 1.0}
    assert load_scenario("joint_2", filename=path).failed_joints == [2]


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
