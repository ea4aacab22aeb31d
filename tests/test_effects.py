"""The library of candidate effects: hand-computed friction laws, the implicit step with every term,
nesting (zero is the paper's model), closed-form motion on a tilted floor, the servo lag against an
independent integration, bad input, and a user's own effect."""

import dataclasses
import math

import numpy as np
import pytest

from rc1_drake.config import Gait, Rc1Error, Scenario, Start, Stop
from rc1_drake.diagram import build_diagram
from rc1_drake.effects import LIBRARY, Effect, EffectParameter, apply_effects, commanded_gait, parse_effect, register
from rc1_drake.friction import implicit_friction_force, wheel_friction_forces
from rc1_drake.protocol import simulate
from rc1_drake.scenarios import validate

PAPER = dict(mu_long=0.12, mu_lat=1.5, c_long=0.14, c_lat=3.75)
M = 0.286  # one module's mass, kg
N = M * 9.81


def test_asymmetric_and_stribeck_laws_by_hand():
    tiny = 1e-9  # sgn() smoothing far below the speeds used: the exact law
    # Sliding left (+y) at 0.02 m/s with a_lat = 0.5: -(3.75 * 0.02 + 1.5 * 2.80566 * 1.5) = -6.387735 N;
    # sliding right: +(0.075 + 1.5 * 2.80566 * 0.5) = +2.179245 N.
    _, left = wheel_friction_forces([0.0], [0.02], normal_force=[N], eps=tiny, lat_asymmetry=0.5, **PAPER)
    _, right = wheel_friction_forces([0.0], [-0.02], normal_force=[N], eps=tiny, lat_asymmetry=0.5, **PAPER)
    assert left[0] == pytest.approx(-6.387735, abs=1e-6) and right[0] == pytest.approx(2.179245, abs=1e-6)
    # Rolling backward at 0.3 m/s with a_long = 0.5: +(0.14 * 0.3 + 0.12 * 2.80566 * 0.5) = 0.210340 N.
    back, _ = wheel_friction_forces([-0.3], [0.0], normal_force=[N], eps=tiny, long_asymmetry=0.5, **PAPER)
    assert back[0] == pytest.approx(0.210340, abs=1e-6)
    # Stribeck r = 1 at v = v_s = 0.01 m/s: -(0.0375 + 4.20849 (1 + e^-1)) = -5.794207 N; far above v_s the
    # breakaway term is gone.
    _, slow = wheel_friction_forces(
        [0.0], [0.01], normal_force=[N], eps=tiny, stribeck_ratio=1.0, stribeck_speed_m_s=0.01, **PAPER
    )
    _, fast = wheel_friction_forces(
        [0.0], [0.5], normal_force=[N], eps=tiny, stribeck_ratio=1.0, stribeck_speed_m_s=0.01, **PAPER
    )
    assert slow[0] == pytest.approx(-5.794207, abs=1e-6)
    assert fast[0] == pytest.approx(-(3.75 * 0.5 + 1.5 * N), rel=1e-9)


def test_implicit_step_with_every_effect_term_solves_backward_euler():
    rng = np.random.default_rng(2)
    n, w, dt, eps = 6, 4, 1e-3, 1e-3
    a = rng.normal(size=(n, n))
    mass = a @ a.T + n * np.eye(n)
    jl, jt, jh = (np.ascontiguousarray(rng.normal(size=s)) for s in ((w, n), (w, n), (2, n)))
    v = rng.normal(scale=0.05, size=n)
    shape = np.array([0.3, -0.2, 0.8, 0.02])
    joint_coulomb = np.array([0, 0, 0, 0.1, 0, 0.05])
    normal = np.full(w, N)
    p_free = mass @ v + dt * np.linspace(-1, 1, n)
    tau = implicit_friction_force(
        jl,
        jt,
        np.zeros(n),
        mass,
        p_free,
        v,
        dt,
        normal_force=normal,
        eps=eps,
        newton_steps=20,
        shape=shape,
        jac_head=jh,
        head_coulomb=0.4 * N,
        joint_coulomb=joint_coulomb,
        joint_eps=0.01,
        **PAPER,
    )
    v_next = np.linalg.solve(mass, p_free + dt * tau)
    f_long, f_lat = wheel_friction_forces(
        jl @ v_next,
        jt @ v_next,
        normal_force=normal,
        eps=eps,
        lat_asymmetry=0.3,
        long_asymmetry=-0.2,
        stribeck_ratio=0.8,
        stribeck_speed_m_s=0.02,
        **PAPER,
    )
    u = jh @ v_next
    f_head = -0.4 * N * u / math.sqrt(u @ u + eps**2)
    f_joint = -joint_coulomb * v_next / np.sqrt(v_next**2 + 0.01**2)
    # The solve ends at Newton steps under 1e-7 m/s: v+ holds to ~1e-9 m/s, the force (M / dt times that) to ~1e-5 N.
    assert np.allclose(tau, jl.T @ f_long + jt.T @ f_lat + jh.T @ f_head + f_joint, rtol=1e-7, atol=1e-5)


SHORT = Scenario(stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0))


def test_every_effect_at_zero_is_the_paper_model():
    zeros = {p.key: p.default for e in LIBRARY.values() for p in e.parameters}
    plain = simulate(scenario=SHORT)
    nested = simulate(scenario=dataclasses.replace(SHORT, effects=zeros))
    assert np.array_equal(plain.state, nested.state)


def _downhill(effects):
    """A straight, still snake (amplitude 0, heading +x) on a floor tilted 10 deg downhill toward +x."""
    scenario = Scenario(
        gait=Gait(amplitude_deg=0.0),
        friction=dataclasses.replace(Scenario().friction, c_long=0.0),
        effects={"ground_slope_deg": 10.0, "ground_slope_direction_deg": 0.0, **effects},
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0),
    )
    return _acceleration(simulate(scenario=validate(scenario)))


def _acceleration(run):
    """The head's (x, y) acceleration after the start, where the speed is inside the sgn() smoothing."""
    late = run.t >= 0.2
    return np.polyfit(run.t[late], run.state[late, 16:18], 1)[0]


@pytest.mark.parametrize(
    "effects, wheel_extra, head_mu, asym",
    [
        ({}, 0.0, 0.0, 0.0),
        ({"head_drag_mu": 0.3}, 0.0, 0.3, 0.0),
        ({"longitudinal_friction_asymmetry": 0.3}, 0.0, 0.0, 0.3),
        ({"payload_kg": 0.5, "payload_module": 5}, 0.5, 0.0, 0.0),
    ],
)
def test_rolling_down_a_tilted_floor_in_closed_form(effects, wheel_extra, head_mu, asym):
    """tan(10 deg) > mu_long: the straight snake rolls forward down the slope at
    a = g [(14 m + p) sin a - (mu_long (1 + a_long) (13 m + p) + mu_head m) cos a] / (14 m + p)."""
    alpha, mu = math.radians(10.0), 0.12
    total = 14 * M + wheel_extra
    acc = (
        9.81
        * (total * math.sin(alpha) - (mu * (1 + asym) * (13 * M + wheel_extra) + head_mu * M) * math.cos(alpha))
        / total
    )
    measured = _downhill(effects)
    assert measured[0] == pytest.approx(acc, rel=1e-3) and abs(measured[1]) < 1e-6


def test_a_sideways_slope_below_mu_lat_holds():
    """Downhill to the snake's left (+y), tan(10 deg) < mu_lat: the wheels do not slide sideways (beyond
    the creep of the smoothed sign, well under a millimetre in a second)."""
    scenario = Scenario(
        gait=Gait(amplitude_deg=0.0),
        effects={"ground_slope_deg": 10.0, "ground_slope_direction_deg": 90.0},
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0),
    )
    run = simulate(scenario=scenario)
    assert abs(run.head_xy[-1, 1] - run.head_xy[0, 1]) < 1e-3


def test_servo_lag_is_the_first_order_response_to_the_serpenoid():
    """After its transient, the lagged command equals an independent integration of tau y' = u - y."""
    from rc1_drake.gait import serpenoid

    gait, tau, dt = Gait(bias_deg=5.0), 0.08, 1e-5
    lagged = commanded_gait(gait, {"servo_lag_s": tau})
    t = np.arange(0.0, 1.5, dt)
    u = np.array([serpenoid(ti, gait)[0] for ti in t[::100]])  # every 1 ms; hold between
    y = np.zeros(13)
    for k in range(len(t)):
        y += dt / tau * (u[k // 100] - y)
    # The zero-order hold delays u by half a millisecond on average; compare at the end, 18 tau in.
    expected = serpenoid(t[-1] + dt - 0.5e-3, lagged)[0]
    assert np.allclose(y, expected, atol=math.radians(0.05))
    assert commanded_gait(gait, {"servo_lag_s": 0.0}) == gait


def test_bad_effects_are_one_line_errors():
    with pytest.raises(
        Rc1Error, match=r"^cli: effects.ground_tilt_deg: unknown effect parameter \(known: ground_slope_deg"
    ):
        validate(Scenario(effects={"ground_tilt_deg": 1.0}), where="cli")
    with pytest.raises(Rc1Error, match=r"effects.ground_slope_deg: must be a number in \[0, 20\], got 35"):
        validate(Scenario(effects={"ground_slope_deg": 35.0}), where="cli")
    assert parse_effect("head_drag=0.3") == ("head_drag_mu", 0.3)
    assert parse_effect("ground_slope_direction_deg=90") == ("ground_slope_direction_deg", 90.0)
    for text, message in (
        ("slope=1", "unknown effect 'slope'"),
        ("head_drag", "needs a value"),
        ("head_drag=x", "not a number"),
    ):
        with pytest.raises(ValueError, match=message):
            parse_effect(text)


def test_a_users_own_effect_with_an_explicit_force(tmp_path):
    """One small class: a tether pulling the head to the left with a constant force."""

    class Tether(Effect):
        name = "test_tether"
        summary = "a cable pulling the head toward +y"
        parameters = (EffectParameter("tether_N", 0.0, 10.0),)

        def configure(self, setup, values):
            force = np.zeros(16)
            force[1] = values["tether_N"]  # the head's y coordinate
            setup.extra_forces.append(lambda x: force)

    register(Tether())
    try:
        scenario = Scenario(
            gait=Gait(amplitude_deg=0.0),
            start=Start(heading_deg=90.0),  # axis along +y: rolls
            friction=dataclasses.replace(Scenario().friction, c_long=0.0),
            effects={"tether_N": 6.0},
            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0),
        )
        measured = _acceleration(simulate(scenario=validate(scenario)))
        assert measured[1] == pytest.approx((6.0 - 0.12 * 13 * N) / (14 * M), rel=1e-3)
        # Per-run values live in the context: two contexts of one Diagram keep their own effects.
        built = build_diagram(scenario)
        contexts = {"pulled": built.diagram.CreateDefaultContext(), "free": built.diagram.CreateDefaultContext()}
        for name, context in contexts.items():
            apply_effects(
                built,
                context,
                scenario.effects if name == "pulled" else {},
                friction=scenario.friction,
                sgn_smoothing_m_s=scenario.numerics.sgn_smoothing_m_s,
            )
        own = {n: built.friction.GetMyContextFromRoot(c) for n, c in contexts.items()}
        assert len(built.friction.known_forces(own["pulled"]).extra) == 1
        assert built.friction.known_forces(own["free"]).extra == ()
        port = built.friction.GetOutputPort("generalized_force")
        assert not np.allclose(port.Eval(own["pulled"]), port.Eval(own["free"]))
    finally:
        del LIBRARY["test_tether"]


def test_effects_reach_a_run_from_the_command_line_and_from_a_model_file(tmp_path):
    """--effect and a model file's effects give the run the Python API gives; a bad one is one line."""
    import json

    from rc1_drake.cli import main
    from rc1_drake.config import Friction
    from rc1_drake.scenarios import model_to_yaml

    effects = {"ground_slope_deg": 4.0, "ground_slope_direction_deg": 90.0, "head_drag_mu": 0.2}
    expected = simulate(scenario=dataclasses.replace(SHORT, friction=Friction(mu_lat=1.2), effects=effects))
    model = tmp_path / "model.yaml"
    model.write_text(model_to_yaml(Friction(mu_lat=1.2), {"ground_slope_deg": 4.0, "head_drag_mu": 0.2}))
    out = tmp_path / "run.json"
    assert (
        main(
            [
                "run",
                "--model-file",
                str(model),
                "--effect",
                "ground_slope_direction_deg=90",
                "--time-limit-s",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    record = json.loads(out.read_text())
    assert np.allclose(record["final_head_xy_m"], expected.head_xy[-1], atol=1e-9)
    model.write_text("friction: {mu_lat: 1.2}\neffects: {head_drag_mu: 5}\n")
    assert main(["run", "--model-file", str(model)]) == 2
