"""fatigue_over_record and rainflow counting.

Truths: the steady robot_value figure (a constant-wind record is the steady analysis), the
rainflow library and ASTM E1049-85's worked sequence, the closed form of a pure sine, the
change of state called directly, RobotLimits.rest_to_rest_time called directly.
"""

import math

import numpy as np
import pytest
import rainflow

import powerline_control as plc
from powerline_control.severity import SECONDS_PER_YEAR
from powerline_control.severity.balance import _sbl_cycles

DRAKE = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
ROBOT = plc.MDR.tuned(0.0, body_mass=6.0, suspended_mass=1.5, frequency=15.0, damping_ratio=0.3)
LIMITS = plc.RobotLimits(v_max=0.3, a_max=0.5)
EXACT = dict(speed_step=None, tension_resolution=None)  # no grouping: the exact balance


@pytest.mark.parametrize("speed", [2.0, 3.0, 5.5])
def test_constant_wind_record_equals_the_steady_robot_value(speed):
    """A record of one steady wind normal to the line at the reference temperature is the
    steady analysis: robot_value with all the probability in that wind speed's bin and the
    record's step as the persistence (the robot starts every record half a loop away:
    move="worst") gives the same damage per year for all three configurations."""
    dist = plc.severity.WindDistribution.histogram([0.5 * speed, 1.5 * speed], [1.0 / speed])
    value = plc.severity.robot_value(DRAKE, ROBOT, LIMITS, [speed], distribution=dist,
                                     persistence=600.0)
    record = plc.WindRecord.constant(speed, n_records=12, step=600.0)
    life = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS, move="worst",
                                   fixed_position=value.fixed_position, **EXACT)
    ours = [life[name].damage_per_year for name in ("no_damper", "fixed_damper", "robot")]
    # same formulas on the same balance; the tension passes through the change of state at
    # zero temperature change (exact to a few ulp), hence 1e-9 rather than equality
    np.testing.assert_allclose(ours, value.fatigue_index, rtol=1e-9)
    np.testing.assert_allclose([life[n].fraction_over_endurance for n in life],
                               value.fraction_over_endurance, rtol=1e-12)
    assert life["robot"].life_years == pytest.approx(1 / value.fatigue_index[2], rel=1e-9)


def test_a_robot_that_stays_put_is_the_robot_at_the_antinode():
    """Tracked moves under a constant wind: after reaching the antinode the robot never moves,
    so its damage is the steady at-antinode damage f x year / N_SBL(sigma)."""
    record = plc.WindRecord.constant(3.0, n_records=6)
    first = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS, **EXACT)
    start = float(first.robot_position[0])
    life = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS, robot_start=start, **EXACT)
    assert np.all(life.move_time == 0.0)
    steady = plc.aeolian_severity(DRAKE, [3.0], (plc.fem.AtAntinode(ROBOT),))
    expected = steady.frequency[0] * SECONDS_PER_YEAR / _sbl_cycles(steady.stress_ps, "multi")[0]
    assert life["robot"].damage_per_year == pytest.approx(expected, rel=1e-9)
    # the first run paid one move, from x* to the antinode, at rest_to_rest_time's price
    distance = abs(start - first.fixed_position)
    assert first.move_time[0] == pytest.approx(LIMITS.rest_to_rest_time(distance), rel=1e-12)
    assert np.all(first.move_time[1:] == 0.0)


def _changing_record():
    # wind speed steps every 10 minutes between 1.5 and 4 m/s, normal to the line
    speeds = np.tile([1.5, 2.0, 2.5, 3.0, 4.0, 3.5, 2.2], 6)
    n = speeds.size
    return plc.WindRecord(np.arange(n) * 600.0, speeds, np.full(n, 90.0), np.full(n, 15.0))


def test_the_robot_parks_on_antinodes_and_pays_its_moves():
    record = _changing_record()
    life = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS)
    loops = life.loop_length
    # every parked position is an antinode (k + 1/2) loop of its record's pattern
    k = life.robot_position / loops - 0.5
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    # move times are rest_to_rest_time of the distance moved (a half loop at most)
    moves = np.abs(np.diff(np.concatenate([[life.fixed_position], life.robot_position])))
    assert np.all(moves <= 0.5 * loops + 1e-9)
    expected = [LIMITS.rest_to_rest_time(d) for d in moves]
    np.testing.assert_allclose(life.move_time, expected, rtol=1e-12)
    # ordering of the three configurations on this record
    d = [life[n].damage_per_year for n in life]
    assert d[2] < d[1] < d[0]


def test_a_slower_robot_does_more_damage_and_an_instant_one_the_least():
    record = _changing_record()
    damage = [plc.fatigue_over_record(DRAKE, record, ROBOT, plc.RobotLimits(v, 10 * v))
              ["robot"].damage_per_year for v in (0.001, 0.003, 0.01, 0.1, 1.0)]
    assert all(a > b for a, b in zip(damage, damage[1:], strict=False))
    # a robot that can never arrive (each move longer than a record) is the moving robot:
    # phi^2 = 1/2 all the time
    crawl = plc.fatigue_over_record(DRAKE, record, ROBOT, plc.RobotLimits(1e-6, 1e-6))
    moving = plc.aeolian_severity(DRAKE, np.unique(record.wind_speed),
                                  (plc.fem.AtAntinode(ROBOT, "moving", 0.5),))
    per_speed = moving.frequency * 600.0 / _sbl_cycles(moving.stress_ps, "multi")
    by_speed = dict(zip(moving.wind_speed.tolist(), per_speed, strict=True))
    total = sum(by_speed[v] for v in record.wind_speed.tolist())
    # the first record's robot starts at x* which is not an antinode, so every record moves
    assert np.all(crawl.move_time > 600.0)
    assert crawl["robot"].damage_per_year == pytest.approx(total / crawl.years, rel=1e-9)


def test_temperature_sets_the_tension_through_the_change_of_state():
    n = 4
    temps = np.array([-10.0, 5.0, 25.0, 40.0])
    record = plc.WindRecord(np.arange(n) * 3600.0, np.full(n, 3.0), np.full(n, 90.0), temps)
    life = plc.fatigue_over_record(DRAKE, record, **EXACT)
    np.testing.assert_allclose(life.tension, plc.tension_at_temperature(DRAKE, temps),
                               rtol=1e-15)
    # each record's no-damper damage is the steady damage at its own tension
    for i in range(n):
        span = plc.Span(DRAKE.length, float(life.tension[i]), DRAKE.conductor)
        sev = plc.aeolian_severity(span, [3.0])
        expected = sev.frequency[0] * 3600.0 / _sbl_cycles(sev.stress_ps, "multi")[0]
        assert life["no_damper"].damage[i] == pytest.approx(expected, rel=1e-9)


def test_wind_along_the_line_and_outside_the_band_does_no_damage():
    n = 3
    record = plc.WindRecord(np.arange(n) * 600.0, np.array([3.0, 9.0, 0.4]),
                            np.array([0.0, 90.0, 90.0]), np.full(n, 15.0))
    life = plc.fatigue_over_record(DRAKE, record)
    assert not life.vibrating.any()
    assert all(life[name].damage_per_year == 0.0 and math.isinf(life[name].life_years)
               for name in life)


def test_turbulence_lowers_the_damage_as_the_steady_balance_says():
    record = plc.WindRecord.constant(3.0, n_records=2, turbulence_intensity=0.1)
    life = plc.fatigue_over_record(DRAKE, record, **EXACT)
    sev = plc.aeolian_severity(DRAKE, [3.0], turbulence_intensity=0.1)
    expected = sev.frequency[0] * SECONDS_PER_YEAR / _sbl_cycles(sev.stress_ps, "multi")[0]
    assert life["no_damper"].damage_per_year == pytest.approx(expected, rel=1e-9)
    laminar = plc.fatigue_over_record(DRAKE, plc.WindRecord.constant(3.0, n_records=2), **EXACT)
    assert life["no_damper"].damage_per_year < laminar["no_damper"].damage_per_year


def test_grouping_changes_the_answer_only_slightly():
    record = _changing_record()
    exact = plc.fatigue_over_record(DRAKE, record, **EXACT)
    grouped = plc.fatigue_over_record(DRAKE, record)    # 0.05 m/s, 0.5 % of the tension
    for name in exact:
        # the speeds sit on the 0.05 grid and the temperature is constant: only the tension
        # rounding (<= 0.25 % of it) moves the balance
        assert grouped[name].damage_per_year == pytest.approx(exact[name].damage_per_year,
                                                              rel=0.05)


def test_result_prints_its_assumptions():
    life = plc.fatigue_over_record(DRAKE, plc.WindRecord.constant(3.0, n_records=2))
    text = life.summary()
    assert "life" in text and "change of state" in text and "Miner" in text
    with pytest.raises(KeyError, match="configurations"):
        life["nothing"]


@pytest.mark.parametrize("option", ["dampers", "label", "turbulence_intensity"])
def test_options_it_sets_itself_are_refused(option):
    with pytest.raises(plc.InputError, match=option):
        plc.fatigue_over_record(DRAKE, plc.WindRecord.constant(3.0, n_records=2),
                                **{option: ()})


@pytest.mark.parametrize("kwargs, match", [
    (dict(record="wind.csv"), "record"), (dict(damper="robot"), "damper"),
    (dict(limits=0.3), "limits"), (dict(move="fast"), "move"), (dict(band=(7.0, 1.0)), "band"),
    (dict(band=3.0), "band"), (dict(fixed_position=400.0), "fixed_position"),
    (dict(speed_step=-1.0), "speed_step"), (dict(en_route="x"), "en_route"),
])
def test_bad_arguments_are_refused(kwargs, match):
    args = dict(span=DRAKE, record=plc.WindRecord.constant(3.0, n_records=2))
    args.update(kwargs)
    with pytest.raises(plc.InputError, match=match):
        plc.fatigue_over_record(**args)


# --------------------------------------------------------------------------- rainflow
ASTM_SEQUENCE = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]


def test_rainflow_on_the_astm_e1049_sequence():
    """ASTM E1049-85 (2017) section 5.4.4's example history -2, 1, -3, 5, -1, 3, -4, 4, -2:
    ranges 3 (0.5 cycle), 4 (1.5), 6 (0.5), 8 (1.0), 9 (0.5), as the standard's Fig. 6 counts
    it and the rainflow library returns."""
    count = plc.severity.rainflow_count(ASTM_SEQUENCE)
    assert count.histogram() == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    assert list(count.histogram().items()) == rainflow.count_cycles(ASTM_SEQUENCE)
    library = list(rainflow.extract_cycles(ASTM_SEQUENCE))
    np.testing.assert_array_equal(count.means, [c[1] for c in library])


def test_rainflow_matches_the_library_on_a_random_history():
    x = np.random.default_rng(3).standard_normal(2000).cumsum()
    ours = plc.severity.rainflow_count(x).histogram()
    theirs = dict(rainflow.count_cycles(x))
    assert ours.keys() == theirs.keys()
    np.testing.assert_allclose(list(ours.values()), list(theirs.values()), rtol=0, atol=1e-12)


@pytest.mark.parametrize("periods", [1, 7, 50])
def test_rainflow_of_a_pure_cosine_is_its_periods(periods):
    """A cosine of amplitude A over N whole periods, sampled on its peaks among other points:
    N cycles of range 2 A (closed form), and Miner damage N / N_SBL(A)."""
    amplitude = 12e6
    t = np.linspace(0.0, periods, 40 * periods + 1)
    stress = amplitude * np.cos(2 * np.pi * t)
    count = plc.severity.rainflow_count(stress)
    np.testing.assert_allclose(count.ranges, 2 * amplitude, rtol=1e-12)  # peaks sampled exactly
    # 2 N reversals of range 2 A: N cycles in all (equal ranges stay in the residue, so the
    # standard's procedure books them as 2 N half cycles)
    assert count.counts.sum() == periods
    damage = plc.severity.rainflow_damage(stress)
    assert damage == pytest.approx(periods / _sbl_cycles(amplitude, "multi"), rel=1e-12)


def test_rainflow_damage_of_the_steady_clamp_stress_is_the_record_damage():
    """One second of the steady clamp stress history sigma_a sin(2 pi f t) (the energy
    balance at 3 m/s, no damper), counted by rainflow, does the damage the record analysis
    books for one second at that wind."""
    sev = plc.aeolian_severity(DRAKE, [3.0])
    f, sigma = float(sev.frequency[0]), float(sev.stress_ps[0])
    periods = 20
    t = np.linspace(0.0, periods / f, 64 * periods + 1)
    counted = plc.severity.rainflow_damage(sigma * np.cos(2 * np.pi * f * t))
    life = plc.fatigue_over_record(DRAKE, plc.WindRecord.constant(3.0, n_records=1, step=1.0),
                                   **EXACT)
    per_period = life["no_damper"].damage[0] / f
    assert counted == pytest.approx(periods * per_period, rel=1e-9)


@pytest.mark.parametrize("bad", [[1.0, math.nan], [[1.0, 2.0]], ["a", "b"], [True, False]])
def test_rainflow_refuses_bad_signals(bad):
    with pytest.raises(plc.InputError):
        plc.severity.rainflow_count(bad)


def test_rainflow_of_a_constant_signal_has_no_range_and_no_damage():
    assert np.all(plc.severity.rainflow_count([1.0, 1.0,
                                               1.0]).ranges == 0.0)   # as the library says
    assert plc.severity.rainflow_count([]).counts.size == 0
    assert plc.severity.rainflow_damage(np.zeros(10)) == 0.0


def test_with_limits_equals_a_fresh_run_with_those_limits():
    record = _changing_record()
    life = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS)
    for limits in (plc.RobotLimits(0.01, 0.05), plc.RobotLimits(2.0, 4.0, j_max=10.0)):
        fresh = plc.fatigue_over_record(DRAKE, record, ROBOT, limits)
        swapped = life.with_limits(limits)
        for name in fresh:
            assert swapped[name].damage_per_year == fresh[name].damage_per_year
        np.testing.assert_array_equal(swapped.move_time, fresh.move_time)
        assert swapped.assumptions == fresh.assumptions
    with pytest.raises(plc.InputError, match="limits"):
        life.with_limits(0.3)


def test_rainflow_of_the_time_domain_stress_history_matches_the_energy_balance():
    """time_domain_check's simulated history (Drake 30 m, 20 % RTS, ~2 m/s, 60 elements),
    counted by rainflow: 8 cycles in 8 periods, and a damage rate equal to the energy balance's
    f / N_SBL(sigma_a) to the simulated amplitude's error raised to the S-N slope (1/0.17 = 5.9:
    -0.13 % in amplitude is -0.8 % in damage), and to f / N_SBL at the simulated amplitude to
    the sampling of the peaks (64 samples per period: cos(pi / 64) - 1 = -0.12 % at worst)."""
    check = plc.severity.time_domain_check(plc.Span.at_rts_fraction(30.0, "drake", 0.2), 2.0,
                                  n_elements=60)
    count = plc.severity.rainflow_count(check.clamp_stress)
    assert count.counts.sum() == pytest.approx(8.0)
    duration = check.clamp_time[-1] - check.clamp_time[0]
    rate = plc.severity.rainflow_damage(check.clamp_stress) / duration
    ebm_rate = check.frequency / _sbl_cycles(check.ebm_stress, "multi")
    assert rate == pytest.approx(ebm_rate, rel=0.02)
    simulated_stress = check.ebm_stress * (1 + check.relative_error)
    assert rate == pytest.approx(check.frequency / _sbl_cycles(simulated_stress, "multi"),
                                 rel=6 * 0.0013)
    pinned = plc.severity.time_domain_check(plc.Span.at_rts_fraction(30.0, "drake", 0.2), 2.0,
                                   n_elements=40, bc="pinned")
    assert pinned.clamp_stress is None          # no clamp, no Poffenberger-Swart history


def test_best_fixed_position_is_the_least_damage_of_its_candidates():
    record = _changing_record()
    best = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS, fixed_position="best")
    search = best.parameters["fixed_search"]
    assert best.fixed_position == search["positions"][int(np.argmin(search["damages"]))]
    # the chosen position's damage, recomputed as a plain fixed position, is that minimum
    again = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS,
                                    fixed_position=best.fixed_position)
    assert again["fixed_damper"].damage_per_year == best["fixed_damper"].damage_per_year
    assert best["fixed_damper"].damage.sum() == pytest.approx(min(search["damages"]), rel=1e-12)
    harmonic = plc.fatigue_over_record(DRAKE, record, ROBOT, LIMITS)
    assert best["fixed_damper"].damage_per_year <= harmonic["fixed_damper"].damage_per_year
    assert harmonic.fixed_position == best.parameters["harmonic_mean_position"]
    with pytest.raises(plc.InputError, match="fixed_position"):
        plc.fatigue_over_record(DRAKE, record, fixed_position="worst")
