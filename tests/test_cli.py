"""The rc1 command: outputs on success, one-line errors on bad input."""

import dataclasses
import json
import subprocess
import sys

import pytest

from rc1_drake.cli import main
from rc1_drake.config import Friction
from rc1_drake.diagnose import THRESHOLDS


def test_run_writes_summary_json_and_plot(tmp_path, capsys):
    out = tmp_path / "deep" / "j7.json"
    plot = tmp_path / "j7.png"
    assert main(["run", "--scenario", "joint_7", "--json", str(out), "--plot", str(plot)]) == 0
    record = json.loads(out.read_text())
    for key in ("final_head_xy_m", "t_final_s", "outcome", "revolutions", "circle_diameter_m", "wall_time_s"):
        assert key in record
    assert record["outcome"] == "crossed" and record["failed_joints"] == [7]
    assert record["final_head_xy_m"][0] >= 3.18
    assert plot.stat().st_size > 20_000  # a real figure, not an empty canvas
    assert "outcome" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "--friction", "mu_side=1"], "unknown friction coefficient 'mu_side'"),
        (["run", "--friction", "mu_lat=abc"], "'abc' is not a number"),
        (["run", "--friction", "mu_lat"], "is not NAME=VALUE"),
        (["run", "--failed-joint", "14"], "joint 14 does not exist"),
        (["run", "--bias-deg", "x"], "'x' is not a number"),
        (["run", "--scenario", "nope"], "no scenario named 'nope'"),
        (["run", "--scenarios-file", "/nonexistent.yaml"], "no such scenario file"),
        (["run", "--friction", "mu_lat=-2"], "friction.mu_lat: must be >= 0"),
        (["run", "--failed-joint", "7", "--scenario", "joint_7"], "joint 7 is listed twice"),
        (["fly"], "invalid choice"),
        (["run", "--animate", "run.gif"], "give a path ending in .html"),
        (["run", "--effect", "slope=1"], "unknown effect 'slope'"),
        (["run", "--effect", "ground_slope=35"], "effects.ground_slope_deg: must be a number in [0, 20], got 35"),
        (["identify", "data/paper_campaign", "--input-noise-samples", "-1"], "-1 must be at least 0"),
        (["synthesize", "/tmp/rc1_never_written", "--time-limit-s", "-1"], "stop.time_limit_s: must be > 0"),
        (["synthesize", "/tmp/rc1_never_written", "--form", "bogus=1"], "unknown form 'bogus'"),
        (
            ["synthesize", "/tmp/rc1_never_written", "--form", "reference_camera_marker_m=0.05"],
            "reference_camera_marker_m: only the reference truth model reads these",
        ),
        (
            [
                "synthesize",
                "/tmp/rc1_never_written",
                "--truth-model",
                "reference",
                "--form",
                "reference_camera_scale_error=0.5",
            ],
            "effects.reference_camera_scale_error: must lie in [-0.1, 0.1], got 0.5",
        ),  # fmt: skip
        (["diagnose", "data/paper_campaign", "--candidates", "wind"], "unknown effect 'wind'"),
        (["diagnose", "data/paper_campaign", "--trials", "nominal_9"], "nominal_9"),
        (["diagnose", "data/paper_campaign", "--model-file", "/nonexistent.yaml"], "/nonexistent.yaml"),
        (["diagnose", "data/paper_campaign", "--failed-joint-scatter", "-1"], "-1 must be a finite number >= 0"),
        (["diagnose", "data/paper_campaign", "--failed-joint-scatter", "inf"], "inf must be a finite number >= 0"),
        pytest.param(["reproduce", "--joints", "2,14"], "joint 14 does not exist", id="reproduce-joints"),
        pytest.param(["reproduce", "--trials", "0"], "0 must be at least 1", id="reproduce-trials"),
        pytest.param(
            ["reproduce", "--time-limit-s", "-5"], "stop.time_limit_s: must be > 0", id="reproduce-time-limit"
        ),
        pytest.param(
            ["reproduce", "--model-file", "/nonexistent.yaml"],
            "/nonexistent.yaml: no such model file",
            id="reproduce-model-file",
        ),
        pytest.param(["reproduce", "--servo", "kp=3"], "unknown servo gain 'kp'", id="reproduce-servo-key"),
        pytest.param(["reproduce", "--servo", "kp_Nm_per_rad=x"], "'x' is not a number", id="reproduce-servo-value"),
        pytest.param(["reproduce", "--servo", "kp_Nm_per_rad"], "is not KEY=VALUE", id="reproduce-servo-form"),
        pytest.param(
            ["reproduce", "--servo", "ki_Nm_per_rad_s=-1"],
            "servo.ki_Nm_per_rad_s: must be >= 0",
            id="reproduce-servo-negative",
        ),
        pytest.param(
            ["reproduce", "--effect", "head_drag_mu=9"],
            "effects.head_drag_mu: must be a number in [0, 2], got 9",
            id="reproduce-effect",
        ),
    ],
)
def test_bad_options_are_one_line_errors(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        code = main(argv)
        raise SystemExit(code)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1 and "Traceback" not in err


def test_console_entry_point_reports_errors_without_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "rc1_drake.cli", "run", "--failed-joint", "0"], capture_output=True, text=True
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "joint 0 does not exist" in proc.stderr


@pytest.mark.parametrize(
    "command, option",
    [
        ("diagnose", "--json"),
        ("diagnose", "--plots"),
        ("diagnose", "--checkpoint"),
        ("diagnose", "--report"),
        ("identify", "--out"),
        ("identify", "--checkpoint"),
        ("compare", "--json"),
        ("run", "--json"),
        ("sweep", "--out"),
        ("reproduce", "--json"),
        ("reproduce", "--plots"),
    ],
)
def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys, command, option):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    target = blocker / "x" / "y.json"
    argv = (
        [command]
        + ([] if command in ("run", "sweep", "reproduce") else ["data/paper_campaign"])
        + [option, str(target)]
    )
    assert main(argv) == 2  # at once: a diagnosis or an identification would take minutes first
    err = capsys.readouterr().err
    assert f"{option} {target}" in err and "cannot write there" in err and err.count("\n") == 1


@pytest.mark.parametrize("given, taken", [([], THRESHOLDS.max_failed_joint_scatter), (["0"], 0.0), (["2.5"], 2.5)])
def test_the_failed_joints_scatter_bound_reaches_the_diagnosis(given, taken, tmp_path, monkeypatch):
    """rc1 diagnose --failed-joint-scatter STEPS sets that one threshold, the others left at their defaults."""
    import rc1_drake.diagnose as diagnose_package

    seen = {}

    class Diagnosed:
        verdict, friction, effects, trials = "no_missing_effect", Friction(), {}, []
        simulations, resumed, wall_s = 0, 0, 0.0

        def format(self):
            return "verdict: no_missing_effect"

    def diagnose(*args, thresholds, **kwargs):
        seen["thresholds"] = thresholds
        return Diagnosed()

    monkeypatch.setattr(diagnose_package, "diagnose", diagnose)
    option = ["--failed-joint-scatter", *given] if given else []
    argv = ["diagnose", "data/paper_campaign", "--out", str(tmp_path / "m.yaml"), "--checkpoint", str(tmp_path / "c")]
    assert main([*argv, *option]) == 0
    assert seen["thresholds"] == dataclasses.replace(THRESHOLDS, max_failed_joint_scatter=taken)
