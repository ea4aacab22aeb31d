"""Equation error: the plant's inverse dynamics agree with the simulator's friction (the fit recovers
the wheel coefficients from the simulator's own states), and on measured-like data it reports what it
cannot see instead of fitting it."""

import json

import numpy as np
import pytest

from rc1_drake.cli import main
from rc1_drake.config import Friction, Gait, Numerics, Scenario, Stop
from rc1_drake.identify.equation_error import WHEEL_NAMES, InverseDynamics, TrajectorySamples, _projected, _solve
from rc1_drake.protocol import simulate
from rc1_drake.synthesize import Case, synthesize_campaign


def test_inverse_dynamics_of_the_simulators_own_states_recovers_the_wheel_friction():
    """A standing wave (clear of the joint limits, whose impulses the base rows do not see but the
    friction prediction does) makes the wheels slip; with the simulator's states at its own step (the velocity
    change of a step and the velocity it ends with, as the implicit friction sees them), the base rows
    are linear in the coefficients and the bounded least squares gives them back."""
    scenario = Scenario(
        gait=Gait(amplitude_deg=30.0, phase_step_deg=0.0, frequency_deg_s=360.0),
        numerics=Numerics(time_step_s=5e-4, log_period_s=5e-4),
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=2.5),
    )
    run = simulate(scenario=scenario)
    q, v = run.state[:, :16], run.state[:, 16:]
    k = np.arange(400, len(run.t) - 2, 5)
    samples = TrajectorySamples("own", run.t[k], q[k], v[k + 1], (v[k + 1] - v[k]) / np.diff(run.t)[k][:, None])
    A, b, used = _projected(InverseDynamics(scenario.numerics.sgn_smoothing_m_s).rows(samples), 5e-3, 5e-3)
    assert len(np.unique(used)) > 50  # samples where at most two wheel directions stick
    theta = dict(zip(WHEEL_NAMES, _solve(A, b, np.zeros(4), np.full(4, 50.0)), strict=True))
    truth = Friction()
    assert theta["mu_lat"] == pytest.approx(truth.mu_lat, rel=0.1)
    assert theta["c_lat"] == pytest.approx(truth.c_lat, rel=0.1)
    assert theta["mu_long"] == pytest.approx(truth.mu_long, rel=0.1)
    # c_long: 0.18 for 0.14; its force is a tenth of the rolling Coulomb term here and barely varies.


def test_equation_error_reports_what_the_paper_gait_cannot_show(tmp_path, capsys):
    """In the paper's gait the wheels slip sideways far below the camera's slip noise: nothing is
    identifiable by equation error, which says so, names the gait that would do, leaves the failure trial
    out, and keeps the start values."""
    folder = tmp_path / "c"
    synthesize_campaign(
        folder, design=[Case([], 1), Case([7], 1)], seed=4, stop=Stop(line_x_m=None, revolutions=None, time_limit_s=2.0)
    )
    out = tmp_path / "ee.json"
    assert (
        main(
            [
                "identify",
                str(folder),
                "--checkpoint",
                str(tmp_path / "checkpoint"),
                "--method",
                "equation-error",
                "--trials",
                "nominal_1",
                "--json",
                str(out),
                "--workers",
                "1",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    record = json.loads(out.read_text())
    assert record["method"] == "equation-error" and record["simulations"] == 0
    assert record["trials_used"] == ["nominal_1"] and record["samples_used"] == 0
    assert not any(record["identifiable"])
    assert record["friction"] == {"c_joint": 0.045, "mu_lat": 1.5, "mu_long": 0.1, "c_lat": 2.0, "c_long": 0.1}
    assert any("phase_step_deg 0" in w for w in record["warnings"])
    assert any(w.startswith("c_joint: not identifiable") for w in record["warnings"])
    held = record["held_out"]
    assert held["estimation_trials"] == ["nominal_1"] and held["validation_trials"] == ["j7_1"]
    assert held["validation_error_pct"] > 0 and "held-out" in printed
