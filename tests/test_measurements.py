"""The strict loader: a valid trial loads; every malformed one fails with a one-line message naming
the file, the line or key, and the problem; a campaign with any bad trial does not load at all."""

import dataclasses
import json
import math
import shutil

import numpy as np
import pytest

from rc1_drake.config import Gait, Rc1Error
from rc1_drake.measurements import Stop, Trial, load_campaign, load_trial, write_trial


def make_trial(failed=(7,), camera=True, n=50):
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.01
    q = 0.5 * np.sin(t[:, None] * 2.4 - np.arange(13) * 0.7) + rng.normal(0, 0.003, (n, 13))
    for j in failed:
        q[:, j - 1] = np.nan
    cam = np.column_stack([t * 0.3, 0.01 * t, 0.1 * np.sin(t)]) if camera else None
    if camera:
        cam[3] = np.nan
    return Trial(
        trial_id="t1",
        failed_joints=list(failed),
        gait=Gait(phase_offset_deg=3.0),
        stop=Stop("line", 3.18),
        initial_head_pose=np.array([0.0, 0.01, 0.2]),
        final_head_xy=np.array([3.2, -0.4]),
        t=t,
        q=q,
        head_yaw_rate=np.cos(t),
        camera=cam,
        notes="test",
    )


@pytest.fixture
def good(tmp_path):
    folder = tmp_path / "campaign"
    write_trial(folder, "t1", make_trial())
    return folder


def rewrite_csv(folder, edit):
    path = folder / "t1.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")
    return path


def rewrite_json(folder, edit):
    path = folder / "t1.json"
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    return path


def set_cell(lines, line, column, value):
    """Set the cell of `column` on file line `line` (1 = the header)."""
    header = lines[0].split(",")
    cells = lines[line - 1].split(",")
    cells[header.index(column)] = value
    lines[line - 1] = ",".join(cells)
    return lines


def expect_error(folder, *fragments):
    with pytest.raises(Rc1Error) as err:
        load_campaign(folder)
    message = str(err.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, message
    return message


def test_round_trip(good):
    trial = load_campaign(good).trials[0]
    original = make_trial()
    assert trial.trial_id == "t1" and trial.failed_joints == [7] and trial.case == "J7"
    assert np.allclose(trial.q, original.q, equal_nan=True) and np.isnan(trial.q[:, 6]).all()
    assert np.allclose(trial.camera, original.camera, equal_nan=True)
    assert trial.gait.phase_offset_deg == 3.0 and trial.stop == Stop("line", 3.18)
    assert np.allclose(trial.final_head_xy, [3.2, -0.4]) and trial.notes == "test"


def test_missing_column(good):
    rewrite_csv(
        good,
        lambda ls: [
            ",".join(c for c in line.split(",")[:-4]) + "," + line.split(",")[-4].replace("head_yaw_rate_rad_s", "x")
            if i == 0
            else line
            for i, line in enumerate(ls)
        ],
    )
    expect_error(good, "t1.csv", "line 1", "missing column head_yaw_rate_rad_s")


def test_unknown_column(good):
    rewrite_csv(good, lambda ls: [line + (",battery_v" if i == 0 else ",7.1") for i, line in enumerate(ls)])
    expect_error(good, "t1.csv", "line 1", "unknown column 'battery_v'")


def test_non_numeric_cell(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 5, "q3_rad", "0.1x"))
    expect_error(good, "t1.csv", "line 5, column q3_rad", "not a number: '0.1x'")


def test_time_not_increasing(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 10, "t_s", "0.05"))
    expect_error(good, "t1.csv", "column t_s", "time does not increase")


def test_time_not_evenly_sampled(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 10, "t_s", "0.0835"))
    expect_error(good, "t1.csv", "line 10, column t_s", "not evenly sampled")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_nan_or_inf(good, value):
    rewrite_csv(good, lambda ls: set_cell(ls, 7, "head_yaw_rate_rad_s", value))
    expect_error(good, "t1.csv", "line 7, column head_yaw_rate_rad_s", "is not a finite number")


def test_joint_reading_past_the_limit_loads_with_one_warning_per_joint(good, tmp_path):
    """A potentiometer that reads high (an offset: joint 2 up to ~43 deg in two trials) is a measurement to
    explain: the campaign loads as measured, and says so once for the joint."""
    trial = make_trial()
    trial.q[:, 1] += math.radians(30.0)
    write_trial(good, "t2", dataclasses.replace(trial, trial_id="t2"))
    write_trial(good, "t3", dataclasses.replace(trial, trial_id="t3"))
    campaign = load_campaign(good)
    loaded = {t.trial_id: t for t in campaign.trials}
    np.testing.assert_allclose(loaded["t2"].q[:, 1], trial.q[:, 1], atol=1e-12)
    assert loaded["t1"].beyond_limit == {} and set(loaded["t2"].beyond_limit) == {2}
    warnings = campaign.warnings()
    assert len(warnings) == 1 and warnings[0].startswith("joint 2's potentiometer reads up to +4")
    assert "in 2 trial(s) (t2, t3)" in warnings[0]


def test_joint_jump_no_servo_can_make(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 8, "q2_rad", repr(math.radians(45))))
    expect_error(good, "t1.csv", "column q2_rad", "more than a servo can move")


def test_failed_joint_with_potentiometer_data(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 4, "q7_rad", "0.1"))
    expect_error(good, "t1.csv", "line 4, column q7_rad", "joint 7 is listed as failed but its potentiometer has data")


def test_working_joint_without_data(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 6, "q5_rad", ""))
    expect_error(good, "t1.csv", "line 6, column q5_rad", "empty cell for working joint 5")


def test_unknown_stop_type(good):
    rewrite_json(good, lambda d: d.update(stop={"type": "wall", "x_m": 3}))
    expect_error(good, "t1.json", "stop.type", 'unknown stop type "wall"')


def test_fewer_than_two_samples(good):
    rewrite_csv(good, lambda ls: ls[:2])
    expect_error(good, "t1.csv", "1 sample(s); at least 2 are needed")


def test_json_without_csv(good):
    (good / "t1.csv").unlink()
    expect_error(good, "t1.json", "its CSV t1.csv is missing")


def test_csv_without_json(good):
    shutil.copy(good / "t1.csv", good / "t2.csv")
    expect_error(good, "t2.csv", "its JSON t2.json is missing")


def test_joint_angles_in_degrees(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 9, "q4_rad", "30.0"))
    expect_error(good, "t1.csv", "line 9, column q4_rad", "30 looks like degrees")


def test_yaw_rate_in_degrees(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 9, "head_yaw_rate_rad_s", "57.3"))
    expect_error(good, "t1.csv", "line 9, column head_yaw_rate_rad_s", "looks like deg/s")


@pytest.mark.parametrize(
    "edit, fragment",
    [
        (lambda d: d.pop("gait"), "gait: missing"),
        (lambda d: d.update(extra=1), "extra: unknown key"),
        (lambda d: d["gait"].update(amplitude_deg="big"), 'gait.amplitude_deg: expected a number, got "big"'),
        (lambda d: d.update(failed_joints=[14]), "failed_joints: joint 14 does not exist"),
        (lambda d: d.update(final_head_xy_m=[1.0]), "final_head_xy_m: expected [x, y]"),
        (lambda d: d["initial_head_pose"].pop("yaw_rad"), "initial_head_pose.yaw_rad: missing"),
        (lambda d: d.update(stop={"type": "revolutions", "count": -2}), "stop.count: must be > 0"),
        (
            lambda d: d.update(initial_head_rates={"vx_m_s": 0.1, "vy_m_s": 0.0}),
            "initial_head_rates.yaw_rate_rad_s: missing",
        ),
        (
            lambda d: d.update(initial_head_rates={"vx_m_s": 0.1, "vy_m_s": None, "yaw_rate_rad_s": 0.0}),
            "initial_head_rates.vy_m_s: expected a number",
        ),
    ],
)
def test_bad_json_keys(good, edit, fragment):
    rewrite_json(good, edit)
    expect_error(good, "t1.json", fragment)


def test_measured_start_rates_round_trip_and_are_optional(good, tmp_path):
    assert load_campaign(good).trials[0].initial_head_rates is None
    given = dataclasses.replace(make_trial(), initial_head_rates=np.array([0.1, -0.02, 0.7]))
    write_trial(tmp_path / "rates", "t1", given)
    assert np.array_equal(load_campaign(tmp_path / "rates").trials[0].initial_head_rates, [0.1, -0.02, 0.7])


def test_invalid_json_names_the_line(good):
    (good / "t1.json").write_text('{\n  "trial_id": "t1",\n  oops\n}')
    expect_error(good, "t1.json", "line 3", "not valid JSON")


def test_partial_camera_row(good):
    rewrite_csv(good, lambda ls: set_cell(ls, 12, "head_y_m", ""))
    expect_error(good, "t1.csv", "line 12", "camera cells are empty together or not at all")


def test_one_bad_trial_stops_the_whole_campaign(good):
    write_trial(good, "t2", Trial(**{**make_trial().__dict__, "trial_id": "t2"}))
    assert len(load_campaign(good).trials) == 2
    rewrite_csv(good, lambda ls: set_cell(ls, 5, "q1_rad", "abc"))
    expect_error(good, "t1.csv", "not a number")


def test_duplicate_trial_ids(good):
    write_trial(good, "t2", make_trial())  # same trial_id "t1" in t2.json
    expect_error(good, "trial_id", "'t1' is used by another trial")


def test_empty_or_missing_folder(tmp_path):
    with pytest.raises(Rc1Error, match="not a campaign folder"):
        load_campaign(tmp_path / "nope")
    with pytest.raises(Rc1Error, match="no trials"):
        load_campaign(tmp_path)


def test_trial_without_camera_loads(tmp_path):
    write_trial(tmp_path, "a", make_trial(failed=(), camera=False))
    trial = load_trial(tmp_path / "a.json")
    assert trial.camera is None and trial.case == "none" and not np.isnan(trial.q).any()
