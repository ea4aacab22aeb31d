"""The tangent kernels (engine/tangent.py) against central differences of the kernels they differentiate."""

import numpy as np
import pytest
from conftest import first_seconds

from rc1_drake.discrepancy import NUM_TERMS
from rc1_drake.engine.dynamics import chain_terms, plant_numbers
from rc1_drake.engine.tangent import chain_tangent, wheel_local_tangent
from rc1_drake.kinematics import wheel_kinematics_kernel

H = 1e-6


def _random(seed, count=4):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=32)
    x[3:16] *= 0.6
    return x, rng.normal(size=(count, 32)), rng.normal(size=(count, 16))


def test_chain_tangent_matches_central_differences():
    numbers = plant_numbers()
    jp, jc, *_ = numbers.geometry.arrays
    mass, inertia, com, gravity = numbers.masses(6, 0.3), numbers.central_yaw_inertia, numbers.com, 0.4 - 0.7j
    for seed in range(3):
        x, dx, w = _random(seed)
        mw, bias, grav = chain_tangent(x, dx, w, mass, inertia, com, jp, jc, gravity)
        for d in range(len(dx)):
            plus = chain_terms(x + H * dx[d], mass, inertia, com, jp, jc, gravity)
            minus = chain_terms(x - H * dx[d], mass, inertia, com, jp, jc, gravity)
            np.testing.assert_allclose(mw[d], (plus[0] - minus[0]) @ w[d] / (2 * H), atol=1e-7)
            np.testing.assert_allclose(bias[d], (plus[1] - minus[1]) / (2 * H), atol=1e-6)
            np.testing.assert_allclose(grav[d], (plus[2] - minus[2]) / (2 * H), atol=1e-7)


def _local(x, arrays):
    _, direction, jacobian = wheel_kinematics_kernel(x, *arrays)
    return np.conj(direction)[:, None] * jacobian


def test_wheel_local_tangent_matches_central_differences():
    numbers = plant_numbers()
    jp, jc, module, offset, toe = numbers.geometry.arrays
    toe = toe * np.exp(1j * 0.03)  # a toed wheel, as the wheel_toe effect makes it
    for seed in range(3):
        x, dx, _ = _random(seed)
        local, dlocal = wheel_local_tangent(x, dx, jp, jc, module, offset, toe)
        np.testing.assert_allclose(local, _local(x, (jp, jc, module, offset, toe)), atol=1e-14)
        for d in range(len(dx)):
            expected = (
                _local(x + H * dx[d], (jp, jc, module, offset, toe))
                - _local(x - H * dx[d], (jp, jc, module, offset, toe))
            ) / (2 * H)
            np.testing.assert_allclose(dlocal[d], expected, atol=1e-8)


# A discrepancy term of every kind (discrepancy.py), small as a fitted one would be.
DISCREPANCY = {
    "discrepancy_tail_dry_long_N": 0.3,
    "discrepancy_front_side_by_long_N_s_per_m": 0.4,
    "discrepancy_middle_drag_lat_N_s_per_m": -0.3,
    "discrepancy_rear_dry_lat_N": 0.2,
    "discrepancy_head_push_lat_N": 0.1,
    "discrepancy_head_drag_long_N_s_per_m": 0.2,
    "discrepancy_rear_push_long_N": -0.1,
    "discrepancy_failed_joint_bias_Nm": 0.02,
    "discrepancy_failed_joint_spring_Nm_per_rad": 0.1,
    "discrepancy_failed_joint_drag_Nm_s_per_rad": 0.01,
    "discrepancy_failed_joint_dry_Nm": 0.01,
}


@pytest.mark.parametrize("stop", [False, True])
def test_friction_tangent_matches_central_differences_of_the_solve(stop):
    """dv+ of the implicit friction and servo step along state, parameter and command directions, against
    central differences of the solve itself (eps = 1 cm/s keeps the law smooth on the difference's scale); with
    `stop`, the free joint 2 deg into a compliant stop, and the stop's parameters among the directions."""
    from rc1_drake import friction as fr
    from rc1_drake.config import Failure, Scenario, Stop
    from rc1_drake.effects import model_setup
    from rc1_drake.engine.session import CompiledSession
    from rc1_drake.engine.tangent import friction_tangent

    numbers = plant_numbers()
    geometry = numbers.geometry
    jp, jc, *_ = geometry.arrays
    scenario = Scenario(failures=[Failure(joint=7)], stop=Stop(time_limit_s=0.6))
    run = CompiledSession().simulate(scenario)
    setup = model_setup(
        {
            "lateral_friction_asymmetry": 0.2,
            "stribeck_ratio": 0.5,
            "head_drag_mu": 0.3,
            "joint_coulomb_Nm": 0.05,
            "wheel_toe_deg": 1.0,
            **DISCREPANCY,
            **({"stop_compliance_rad_per_Nm": 0.02, "stop_d_Nm_s_per_rad": 0.1} if stop else {}),
        }
    )
    params = fr.friction_parameters(friction=scenario.friction, sgn_smoothing_m_s=0.01, setup=setup, geometry=geometry)
    params[fr.FAILED][6] = fr.FREE
    rng = np.random.default_rng(2)
    command = rng.normal(scale=0.3, size=13)
    power, gains, dt = numbers.effort_limit, np.array([20.0, 0.2]), 1e-3
    mass, inertia, com = numbers.masses(), numbers.central_yaw_inertia, numbers.com
    bodies = np.column_stack([mass, inertia, com.real, com.imag])

    def v_plus(x, p, u):
        M, bias, _ = chain_terms(x, mass, inertia, com, jp, jc, 0j)
        force, servo, _ = fr.friction_step(
            x, -bias, M, dt, p, 50, fr.TANGENT_FINAL_STEP_M_S, u, power, gains, geometry.arrays, bodies
        )
        return np.linalg.solve(M, M @ x[16:] + dt * (-bias + force + servo))

    x = run.state[40].copy()
    keys = [fr.MU_LAT, fr.MU_LONG, fr.C_LAT, fr.C_LONG, fr.C_JOINT, 6, 7, 8, fr.HEAD_MU, fr.JOINT_COULOMB]
    if stop:
        x[3 + 6] = -(params[fr.STOP_ONSET] + np.radians(2.0))
        keys += [fr.STOP_K, fr.STOP_D, fr.STOP_ONSET]
    count = len(keys) + 4
    dx = np.zeros((count, 32))
    dparams = np.zeros((count, len(params)))
    dcommand = np.zeros((count, 13))
    for d, key in enumerate(keys):
        dparams[d, key] = 1.0
    dparams[len(keys), fr.toe_slice(13)] = 1.0  # every wheel's toe
    disc = fr.discrepancy_slice(13)
    dparams[len(keys) + 1, disc] = rng.normal(size=NUM_TERMS)  # every discrepancy term at once
    dx[len(keys) + 2] = rng.normal(size=32) * np.r_[np.full(16, 0.05), np.full(16, 0.2)]
    dcommand[len(keys) + 3] = rng.normal(size=13)
    base = v_plus(x, params, command)
    M, bias, _ = chain_terms(x, mass, inertia, com, jp, jc, 0j)
    mw, dbias, _ = chain_tangent(x, dx, np.tile(base - x[16:], (count, 1)), mass, inertia, com, jp, jc, 0j)
    tangent = friction_tangent(
        x, dx, dparams, dcommand, -dbias, mw, base, M, -bias, dt, params, command, power, gains, geometry.arrays
    )
    h = 1e-5
    for d in range(count):
        expected = (
            v_plus(x + h * dx[d], params + h * dparams[d], command + h * dcommand[d])
            - v_plus(x - h * dx[d], params - h * dparams[d], command - h * dcommand[d])
        ) / (2 * h)
        scale = np.abs(expected).max()
        assert scale > 1e-6, d  # the direction moves the step
        np.testing.assert_allclose(tangent[d], expected, atol=1e-3 * scale, err_msg=f"direction {d}")


@pytest.mark.parametrize("damping, tolerance", [(0.0, 1e-4), (0.1, 5e-3)])
def test_run_sensitivities_through_a_compliant_stop_match_central_differences(damping, tolerance):
    """d final state / d (friction, the start's yaw rate) of a 1.5 s run whose free joint 2 swings past 38 deg into
    a compliant stop in place of its limit (the stop's torque in the tangent), against central differences. The
    stop's damping starts at its onset, a jump in the force the tangent of each step cannot see: 0.2% here."""
    import dataclasses

    from rc1_drake.config import Failure, Scenario, Stop
    from rc1_drake.engine.session import CompiledSession
    from rc1_drake.protocol import initial_state

    session = CompiledSession()
    stop = {"stop_compliance_rad_per_Nm": 0.05, "stop_d_Nm_s_per_rad": damping}
    scenario = Scenario(failures=[Failure(joint=2)], stop=Stop(time_limit_s=1.5), effects=stop)
    names = ["mu_lat", "c_lat", "c_joint", "start_head_yaw_rate_rad_s"]
    x0 = initial_state(scenario, session.geometry)
    exact = session.simulate(scenario, initial=x0, sensitivities=names)
    assert np.degrees(np.abs(exact.q[:, 1])).max() > 39.0  # in the stop, past the stiff limit it replaces
    for p, name in enumerate(names[:3]):
        expected = _central(
            lambda s, **kw: session.simulate(s, initial=x0, **kw),
            lambda n, h: dataclasses.replace(
                scenario, friction=dataclasses.replace(scenario.friction, **{n: getattr(scenario.friction, n) + h})
            ),
            name,
        )
        scale = tolerance * np.abs(expected).max()
        np.testing.assert_allclose(exact.sensitivity[-1, p], expected, atol=scale, err_msg=name)
    shift = np.zeros(32)
    shift[18] = 1e-5
    ends = [session.simulate(scenario, initial=x0 + s * shift, sensitivities=names[3:]).state[-1] for s in (1, -1)]
    expected = (ends[0] - ends[1]) / 2e-5
    np.testing.assert_allclose(exact.sensitivity[-1, 3], expected, atol=tolerance * np.abs(expected).max())


def _central(simulate, scenario_at, name):
    """Central differences of two runs solved as tightly as a differentiated run (friction.TANGENT_FINAL_STEP_M_S:
    a run asked for any sensitivity); a plain run's looser stop would be differenced at h too."""
    h = 1e-4 if name.endswith("_deg") else 1e-5  # where round-off and truncation balance, measured
    ends = [simulate(scenario_at(name, s * h), sensitivities=[name]).state[-1] for s in (1, -1)]
    return (ends[0] - ends[1]) / (2 * h)


def test_run_sensitivities_match_central_differences_of_whole_runs():
    """d final state / d parameter of a 0.3 s joint-7 run on a 2 deg slope with every effect of the friction law
    switched on (a falling Stribeck law included), and of a 0.6 s replay of the shipped joint-2 trial on a level
    floor (stiff servos beyond the plant's effort clamp, a free joint near the head), against central
    differences of the runs: every parameter and diagnosis coordinate with a sensitivity."""
    import dataclasses

    from rc1_drake.config import FRICTION_NAMES, Failure, Scenario, Stop
    from rc1_drake.effects import shifted
    from rc1_drake.engine.session import CompiledSession, sensitivity_parameters
    from rc1_drake.measurements import load_trial
    from rc1_drake.replay import Replayer, replay_scenario

    effects = {
        "lateral_friction_asymmetry": 0.1,
        "longitudinal_friction_asymmetry": -0.1,
        "stribeck_ratio": 0.3,
        "head_drag_mu": 0.1,
        "joint_coulomb_Nm": 0.02,
        "wheel_toe_deg": 0.5,
        **DISCREPANCY,
    }

    def varied(scenario, name, h):
        if name in FRICTION_NAMES:
            return dataclasses.replace(
                scenario,
                friction=dataclasses.replace(scenario.friction, **{name: getattr(scenario.friction, name) + h}),
            )
        return dataclasses.replace(scenario, effects=shifted(scenario.effects, name, h))

    session = CompiledSession()
    run_scenario = Scenario(
        failures=[Failure(joint=7)],
        stop=Stop(time_limit_s=0.3),
        effects={**effects, "ground_slope_deg": 2.0, "ground_slope_direction_deg": 30.0},
    )
    trial = first_seconds(load_trial("data/paper_campaign/j2_1.json"), 0.6)
    replayer = Replayer(trial, engine="compiled")
    replay = replay_scenario(trial, run_scenario.friction, effects, replayer.numerics)
    # below: the start's own test; of the discrepancy's terms, those set (their every kind)
    every = [n for n in sensitivity_parameters() if not n.startswith(("start_", "discrepancy_")) or n in DISCREPANCY]
    assert {"mu_lat", "wheel_toe_deg", "ground_slope_x_deg", "ground_slope_direction_deg"} <= set(every)
    cases = [
        (lambda s, **kw: session.simulate(s, **kw), run_scenario, every),
        # on a level floor the slope's direction does nothing
        (
            lambda s, **kw: replayer.session.simulate(s, initial=replayer.initial, **kw),
            replay,
            [n for n in every if n != "ground_slope_direction_deg"],
        ),
    ]
    for simulate, scenario, names in cases:
        exact = simulate(scenario, sensitivities=names)
        assert exact.sensitivity.shape == (len(exact.t), len(names), 32)
        for p, name in enumerate(names):
            expected = _central(simulate, lambda n, h, scenario=scenario: varied(scenario, n, h), name)
            scale = np.abs(expected).max()
            assert scale > 1e-4, name  # not trivially zero
            np.testing.assert_allclose(exact.sensitivity[-1, p], expected, atol=1e-4 * scale, err_msg=name)


def test_sensitivities_by_an_unknown_name_or_on_the_drake_engine_are_refused():
    import pytest

    from rc1_drake.config import Rc1Error, Scenario, Stop
    from rc1_drake.engine.session import CompiledSession
    from rc1_drake.protocol import Session

    scenario = Scenario(stop=Stop(time_limit_s=0.01))
    for name in ("payload_kg", "servo_lag_s", "no_such_parameter"):  # the masses, the gait command; unknown
        with pytest.raises(ValueError, match=f"no sensitivity for '{name}'"):
            CompiledSession().simulate(scenario, sensitivities=[name])
    with pytest.raises(Rc1Error, match="need the compiled engine"):
        Session(scenario).simulate(scenario, sensitivities=["mu_lat"])


@pytest.mark.parametrize("rule", ["line", "turn"])
def test_sensitivities_at_a_stop_event_follow_the_moving_stop_time(rule):
    """A run that stops where the head crosses a line, or where its yaw has turned by 0.06 revolutions: its last
    sample's sensitivities are those of the state at the event (the stop time moves with the parameter),
    against central differences of the runs' states interpolated to the event (every step logged)."""
    import dataclasses

    from rc1_drake.config import Numerics, Scenario, Stop
    from rc1_drake.engine.session import CompiledSession

    stop = Stop(line_x_m=0.2, time_limit_s=1.0) if rule == "line" else Stop(revolutions=0.06, time_limit_s=1.0)
    coordinate = 0 if rule == "line" else 2
    scenario = Scenario(stop=stop, numerics=Numerics(log_period_s=0.0), effects={"wheel_toe_deg": 0.5})
    session = CompiledSession()

    def at_event(s):
        run = session.simulate(s)
        assert run.stop_reason == ("crossed" if rule == "line" else "circling")
        before, after = run.state[-2], run.state[-1]
        threshold = 0.2 if rule == "line" else run.state[0, 2] + np.sign(after[2] - run.state[0, 2]) * 0.12 * np.pi
        return before + (threshold - before[coordinate]) / (after[coordinate] - before[coordinate]) * (after - before)

    names = ["mu_lat", "c_long", "wheel_toe_deg"]
    exact = session.simulate(scenario, sensitivities=names).sensitivity[-1]
    for p, name in enumerate(names):
        h = 1e-4 if name.endswith("_deg") else 1e-5
        if name.endswith("_deg"):
            up, down = ({**scenario.effects, name: scenario.effects[name] + d} for d in (h, -h))
            up, down = (dataclasses.replace(scenario, effects=e) for e in (up, down))
        else:
            up, down = (
                dataclasses.replace(
                    scenario,
                    friction=dataclasses.replace(scenario.friction, **{name: getattr(scenario.friction, name) + d}),
                )
                for d in (h, -h)
            )
        expected = (at_event(up) - at_event(down))[:16] / (2 * h)
        assert abs(expected[coordinate]) < 1e-6 * np.abs(expected).max()  # the stop rule's coordinate is fixed
        np.testing.assert_allclose(exact[p, :16], expected, atol=1e-3 * np.abs(expected).max(), err_msg=name)


def test_sensitivities_by_the_start_rates_match_central_differences():
    """d final state / d (the start's head rates) of a 0.3 s joint-7 run, against runs from shifted starts."""
    from rc1_drake.config import Failure, Scenario, Stop
    from rc1_drake.engine.session import START_RATES, CompiledSession
    from rc1_drake.protocol import initial_state

    session = CompiledSession()
    scenario = Scenario(failures=[Failure(joint=7)], stop=Stop(time_limit_s=0.3))
    x0 = initial_state(scenario, session.geometry)
    exact = session.simulate(scenario, initial=x0, sensitivities=list(START_RATES)).sensitivity[-1]
    h = 1e-5
    for p, index in enumerate(START_RATES.values()):
        shift = np.zeros(32)
        shift[index] = h
        expected = (
            session.simulate(scenario, initial=x0 + shift).state[-1]
            - session.simulate(scenario, initial=x0 - shift).state[-1]
        ) / (2 * h)
        assert np.abs(expected).max() > 1e-2
        np.testing.assert_allclose(exact[p], expected, atol=1e-4 * np.abs(expected).max())
