"""Replay and comparison on synthesized campaigns: noise only gives the paper's Eq. 6 error below 2%;
a hidden physical effect gives clearly more; replayed joints track the measured ones within 0.5 deg."""

import json

import numpy as np
import pytest

from rc1_drake.cli import main
from rc1_drake.compare import compare_campaign, fit_percent, simulator_error
from rc1_drake.config import Stop
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import Case, synthesize_campaign

DESIGN = [Case([], 2), Case([7], 1)]
SHORT = Stop(line_x_m=None, revolutions=None, time_limit_s=5.0)  # short trials keep the suite fast


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clean") / "campaign"
    synthesize_campaign(folder, design=DESIGN, stop=SHORT, seed=11)
    campaign = load_campaign(folder)
    return campaign, compare_campaign(campaign, workers=2)


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hidden") / "campaign"
    synthesize_campaign(folder, design=DESIGN, stop=SHORT, seed=11, effects={"wheel_toe_deg": 3.0})
    return compare_campaign(load_campaign(folder), workers=2)


def test_eq6_and_fit_by_hand():
    # Start at the origin, measured end (3, 4) (5 m travelled), predicted (3, 4.5): 10%.
    assert simulator_error([3, 4.5], [3, 4], [0, 0]) == pytest.approx(10.0)
    y = np.array([1.0, 2.0, 3.0])
    assert fit_percent(y, y) == 100.0 and fit_percent(y, np.full(3, 2.0)) == pytest.approx(0.0)


def test_noise_only_campaign_scores_below_two_percent(clean):
    campaign, report = clean
    assert report.mean_eq6_error_pct < 2.0
    assert len(report.trials) == 3 and set(report.cases()) == {"none", "J7"}
    for r in report.trials:
        assert r.yaw_rate_fit_pct > 80.0  # the IMU trace is reproduced
        assert r.camera_fit_pct["x"] > 90.0


def test_replayed_joints_track_the_measured_angles(clean):
    _, report = clean
    for r in report.trials:
        assert r.tracking_rms_deg < 0.5  # measured noise alone is 0.25 deg RMS


def test_hidden_effect_shows_as_a_larger_error(clean, hidden):
    _, report = clean
    assert hidden.mean_eq6_error_pct > max(3.0, 2.5 * report.mean_eq6_error_pct)


def test_compare_command_writes_table_json_and_plots(clean, tmp_path, capsys):
    campaign, _ = clean
    out = tmp_path / "report.json"
    assert main(["compare", str(campaign.path), "--json", str(out), "--plots", str(tmp_path / "plots"),
                 "--workers", "2"]) == 0
    printed = capsys.readouterr().out
    assert "Failure joint" in printed and "J7" in printed
    data = json.loads(out.read_text())
    assert {"mean_eq6_error_pct", "cases", "trials"} <= set(data)
    assert {t["trial_id"] for t in data["trials"]} == {t.trial_id for t in campaign.trials}
    assert data["cases"]["none"]["mean_eq6_error_pct"] >= 0
    pngs = sorted(p.name for p in (tmp_path / "plots").glob("*.png"))
    assert pngs == ["paths_J7.png", "paths_none.png", "residuals_J7.png", "residuals_none.png",
                    "yaw_rate_J7.png", "yaw_rate_none.png"]
    assert all((tmp_path / "plots" / p).stat().st_size > 10_000 for p in pngs)


def test_synthesize_command_refuses_to_overwrite(tmp_path, capsys):
    (tmp_path / "c").mkdir()
    assert main(["synthesize", str(tmp_path / "c")]) == 2
    assert "already exists" in capsys.readouterr().err
