"""The record of a line in the self-limiting aeolian wind (``severity.simulate_self_limiting``).

Independent truths: the energy balance (``aeolian_severity``, a root of P_w = P_c, no time
stepping), ``simulate_aeolian`` (its own adaptive blocks and settling test, its own sampled final
window), the pinned string's closed-form standing wave sin(n pi x / L), and ``simulate``'s own
records for the fixed lift.
"""

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.errors import InputError
from powerline_control.severity import aeolian_severity, simulate_aeolian, simulate_self_limiting

LENGTH = 30.0
SPAN = plc.Span.at_rts_fraction(LENGTH, "drake", 0.2)
WIND = 3.0
MODEL = plc.LineModel(SPAN, bc="pinned")


def _amplitude(snap, last):
    """Antinode amplitude zero-to-peak: sqrt(2 mean y^2), largest over the positions, over the
    last ``last`` samples."""
    return float(np.sqrt(2 * np.mean(snap.true_displacement[:, -last:] ** 2, axis=1)).max())


def _locked_mode():
    """0-based index of the pinned string's mode nearest St V / D (closed form)."""
    shedding = plc.AeolianForce(WIND).strouhal * WIND / SPAN.conductor.diameter
    return int(np.argmin(np.abs(SPAN.pinned_frequencies(40) - shedding)))


BALANCE = float(aeolian_severity(SPAN, [WIND], bc="pinned").amplitude[0])


def test_a_line_started_below_the_balance_settles_at_it():
    # 10 % below the balance: the wind's negative damping outweighs the self-damping and the
    # amplitude grows to where they meet (an approach of ~100 s on this span; a start from half
    # the balance takes ~400 s). Recorded on a 0.25 m grid (loops of 3.3 m: the grid misses an
    # antinode by < 0.2 %).
    snap = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 200.0, 5e-3,
                                  initial_modes={_locked_mode(): 0.9 * BALANCE},
                                  outputs=np.linspace(0.0, LENGTH, 121))
    first = float(np.sqrt(2 * np.mean(snap.true_displacement[:, :400] ** 2, axis=1)).max())
    assert first == pytest.approx(0.9 * BALANCE, rel=0.01)
    # measured 0.4 % above the balance after 200 s: the damping held over 10 ms blocks and a
    # 10 s window; 2 % leaves room for neither
    assert _amplitude(snap, 2000) == pytest.approx(BALANCE, rel=0.02)


def test_the_record_agrees_with_simulate_aeolian():
    run = simulate_aeolian(SPAN, WIND, bc="pinned")
    snap = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 2.0, 1e-3)
    # the record starts at the balance and stays there (measured 0.3 % below); simulate_aeolian
    # stops within its 1 % settle_tolerance (0.5 % above): 0.8 % apart, 2 % allowed
    assert _amplitude(snap, 1000) == pytest.approx(run.amplitude, rel=0.02)
    assert snap.inputs.shape == (0, snap.t.size) and snap.force_positions == ()
    assert snap.supports == ("pinned", "pinned")


def test_the_record_is_the_locked_modes_standing_wave():
    snap = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 1.0, 1e-3)
    u, s, _ = np.linalg.svd(snap.true_displacement, full_matrices=False)
    # one shape in time: a standing wave, no travelling part (which would need two)
    assert s[1] < 1e-6 * s[0]
    n = _locked_mode() + 1
    shape = np.sin(n * np.pi * snap.x / LENGTH)
    measured = u[:, 0] * np.sign(u[:, 0] @ shape) / np.abs(u[:, 0]).max()
    # Hermite cubic elements reproduce the pinned string's sine to ~1e-4 on this mesh
    assert np.abs(measured - shape / np.abs(shape).max()).max() < 1e-2


def test_final_state_is_the_last_sample_over_the_free_dofs():
    snap = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 0.5, 1e-3)
    field = MODEL.displacement_map() @ snap.final_state[0]
    assert np.allclose(field, snap.true_displacement[:, -1], rtol=0, atol=1e-12 * BALANCE)
    assert snap.final_state[1].shape == (MODEL.n_dofs,)


def test_a_parked_robot_brings_the_line_down_to_where_simulate_aeolian_settles():
    robot = plc.tune_damper(MODEL, 9, 15.0, 3.0, body_mass=5.0)
    loaded = MODEL.with_robot(robot)
    snap = simulate_self_limiting(loaded, plc.AeolianForce(WIND), 20.0, 1e-3)
    # the line starts at the bare balance, as the closed loop's does (the robot's force adds
    # its local field beyond the basis: measured 8 % above it at the first samples)
    start = float(np.abs(snap.true_displacement[:, :100]).max())
    assert 0.95 * BALANCE < start < 1.15 * BALANCE
    truth = simulate_aeolian(SPAN, WIND, robot, bc="pinned", settle_tolerance=0.001)
    # the absorber beats with the line at 0.2 mm, so simulate_aeolian's 20-period window reads
    # 0.158 mm (0.207 mm at its default tolerance); the record's last 2 s 0.178 mm (the same
    # after 60 s): 13 % apart
    assert _amplitude(snap, 2000) == pytest.approx(truth.amplitude, rel=0.2)
    # the absorber's DOF closes the model's free DOFs; the field beyond the basis that the
    # robot's force drives (measured 1e-4 of the amplitude) is not in them
    assert snap.final_state[0].shape == (loaded.n_dofs,)
    field = loaded.displacement_map() @ snap.final_state[0]
    assert np.abs(field - snap.true_displacement[:, -1]).max() < 1e-3 * _amplitude(snap, 2000)


def test_noise_and_outputs_follow_simulates_meaning():
    outputs = [7.5, 15.0]
    snap = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 0.2, 1e-3, outputs=outputs,
                                  noise_fraction=0.01, seed=3, start_time=5.0)
    assert snap.displacement.shape == (2, 201) and snap.t[0] == 5.0
    rms = float(np.sqrt(np.mean(snap.true_displacement**2)))
    assert snap.noise_std == pytest.approx(0.01 * rms)
    again = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 0.2, 1e-3, outputs=outputs,
                                   noise_fraction=0.01, seed=3, start_time=5.0)
    assert np.array_equal(snap.displacement, again.displacement)
    # the positions' field is the nodes' one where they coincide (7.5 and 15 m are nodes)
    full = simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 0.2, 1e-3)
    rows = [int(np.argmin(np.abs(full.x - x))) for x in outputs]
    assert np.allclose(snap.true_displacement, full.true_displacement[rows], rtol=0,
                       atol=1e-12 * BALANCE)


def test_simulate_itself_is_the_fixed_lift():
    # the fixed lift has one home, simulate: its record of the same wind never settles at the
    # balance (its lift does not depend on the amplitude)
    fixed = plc.simulate(MODEL, plc.AeolianForce(WIND), 0.2, 1e-3)
    assert fixed.inputs.shape == (1, fixed.t.size)
    with pytest.raises(InputError, match=r"'wind'.*'fixed_lift'.*simulate\(model"):
        simulate_self_limiting(MODEL, plc.AeolianForce(WIND), 0.2, 1e-3, wind="fixed_lift")


@pytest.mark.parametrize(("model", "force", "options", "match"), [
    (MODEL, plc.AeolianForce(WIND), {"wind": "foo"}, r"'wind'.*'foo'"),
    (MODEL, plc.AeolianForce(WIND), {"wind": {"lift": 1.0}}, r"'wind'.*\['lift'\]"),
    (MODEL, plc.HarmonicForce(1.0, 19.7, 10.0), {}, r"'wind'.*HarmonicForce"),
    (plc.LineModel(SPAN, bc=("pinned", "clamped")), plc.AeolianForce(WIND), {},
     r"bc=\('pinned', 'clamped'\)"),
    (MODEL, plc.AeolianForce(WIND), {"n_modes": 10}, r"'n_modes'.*n_modes=10"),
    (MODEL, plc.AeolianForce(WIND), {"quasi_static": False}, r"'quasi_static'.*False"),
    (MODEL, plc.AeolianForce(WIND), {"initial_state": (np.zeros(3), np.zeros(3))},
     r"'initial_state'"),
    (MODEL, plc.AeolianForce(WIND), {"initial_modes": {0: 1e-3}}, r"'initial_modes' key 0"),
])
def test_bad_input_names_the_parameter_and_the_value(model, force, options, match):
    with pytest.raises(InputError, match=match):
        simulate_self_limiting(model, force, 0.2, 1e-3, **options)


SCENARIO = "\n".join([
    "[span]", 'preset = "conductor"', 'conductor = "drake"', "length = 30.0",
    "rts_fraction = 0.2", "[model]", 'bc = "pinned"', "[forcing]", 'kind = "aeolian"',
    "wind_speed = 3.0", "[simulation]", "duration = 1.2", "dt = 0.001", "seed = 4",
    "[identification]", "shaker = 0.0", "[severity]", "enabled = true"])


@pytest.mark.parametrize("wind", ["fixed_lift", "self_limiting"])
def test_the_scenarios_records_are_simulated_in_the_closed_loops_wind(wind):
    from powerline_control.scenario.stages import wind_physics

    scenario = plc.load_scenario(text=SCENARIO + f'\n[robot]\nwind = "{wind}"')
    records = plc.run_scenario(scenario, stages=("model", "records")).records
    model = scenario.model.build(scenario.span.build())
    sim = scenario.simulation
    if wind == "fixed_lift":   # the default: simulate's record, as before
        direct = plc.simulate(model, scenario.forcing.build(), duration=sim.duration,
                              dt=sim.dt, noise_fraction=sim.noise_fraction, seed=sim.seed)
    else:
        direct = simulate_self_limiting(model, scenario.forcing.build(), duration=sim.duration,
                                        dt=sim.dt, wind=wind_physics(scenario, model.span),
                                        noise_fraction=sim.noise_fraction, seed=sim.seed)
    assert np.array_equal(records.test.displacement, direct.displacement)
    assert records.train is records.test


def test_a_scenario_refuses_a_shaker_in_the_self_limiting_wind_when_it_simulates_records():
    text = SCENARIO.replace("shaker = 0.0", "shaker = 0.1") + '\n[robot]\nwind = "self_limiting"'
    scenario = plc.load_scenario(text=text)    # a closed loop alone needs no record: loaded
    with pytest.raises(InputError, match=r"identification.shaker = 0.1 is not allowed"):
        plc.run_scenario(scenario, stages=("model", "records"))
