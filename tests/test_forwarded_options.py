"""Misspelt keywords of the public ``**options`` functions: refused by name, before any work.

Every public function that takes ``**something`` and passes it on checks the names first with
``_validation.check_forwarded_options``: the message names the unknown keyword, the nearest
accepted one and the accepted names (the function's own and those it passes on). The target is
replaced by one that fails the test if it is called (same signature): the refusal must come
before the work. ``parameter_grid(**axes)`` is not here: its keywords are free axis names,
passed on to nothing.
"""

from __future__ import annotations

import functools
import inspect

import control as ct
import numpy as np
import pytest

import powerline_control as plc
from powerline_control import _validation
from powerline_control.estimate import result as estimate_result
from powerline_control.recipe import count as recipe_count
from powerline_control.sensors import count as sensors_count
from powerline_control.severity import checks as severity_checks
from powerline_control.severity import climate as severity_climate
from powerline_control.severity import fatigue as severity_fatigue

DRAKE = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
SYS = ct.ss(np.diag([0.9, 0.8]), np.ones((2, 1)), np.eye(2), 0, dt=0.01)
ROBOT = plc.MDR.tuned(0.0, 5.0, 1.5, frequency=15.0, damping_ratio=0.3)


def _never(original):
    """``original``'s signature (what the check reads), but failing the test if called."""
    @functools.wraps(original)
    def never(*args, **kwargs):
        raise AssertionError("the work started before the keywords were checked")

    return never


def _estimate():
    y = np.random.default_rng(0).normal(size=(1, 200))
    return plc.KalmanFilter(ct.ss([[0.9]], [[0.0]], [[1.0]], 0, dt=0.01), Q=0.01,
                            R=1.0).filter(y)


def _snapshots():
    model = plc.LineModel(plc.Span.paper_lab(), n_elements=10)
    return plc.simulate(model, plc.HarmonicForce(1.0, 9.0, 1.1), duration=0.6, dt=1e-3)


# (id, module whose target is replaced, target's name there, call, misspelt, nearest name)
CASES = [
    ("time_domain_check", severity_checks, "aeolian_severity",
     lambda: plc.severity.time_domain_check(DRAKE, 3.0, n_elements=60, wind_curv="cigre"),
     "wind_curv", "wind_curve"),
    ("robot_value", severity_climate, "aeolian_severity",
     lambda: plc.severity.robot_value(DRAKE, ROBOT, plc.RobotLimits(0.3, 0.5), [2.0],
                                      strouhl=0.2),
     "strouhl", "strouhal"),
    ("fatigue_over_record", severity_fatigue, "aeolian_severity",
     lambda: plc.fatigue_over_record(DRAKE, plc.WindRecord.constant(3.0, n_records=2),
                                     self_damping_kk=1.0),
     "self_damping_kk", "self_damping_k"),
    ("sensor_count_study", sensors_count, "select_sensors",
     lambda: plc.sensors.sensor_count_study(SYS, [1], Q=np.eye(2), R=1.0, n_randm=3),
     "n_randm", "n_random"),
    ("estimator_count_study", recipe_count, "design_estimator",
     lambda: plc.recipe.estimator_count_study(_snapshots(), [2], delays=2, rnk=4),
     "rnk", "rank"),
    ("Estimate.recovery", estimate_result, "recovery_time",
     lambda: _estimate().recovery(100, hlod=5),
     "hlod", "hold"),
]


@pytest.mark.parametrize(("module", "target", "call", "misspelt", "nearest"),
                         [pytest.param(*row[1:], id=row[0]) for row in CASES])
def test_a_misspelt_option_is_refused_by_name_before_any_work(monkeypatch, module, target, call,
                                                              misspelt, nearest):
    monkeypatch.setattr(module, target, _never(getattr(module, target)))
    with pytest.raises(plc.InputError) as info:
        call()
    message = str(info.value)
    assert f"unknown keyword argument {misspelt!r}" in message, message
    assert f"did you mean {nearest!r}" in message, message
    assert "Accepted:" in message and nearest in message.split("Accepted:")[1], message


def test_the_accepted_names_are_the_functions_own_and_the_targets():
    with pytest.raises(plc.InputError) as info:
        plc.severity.time_domain_check(DRAKE, 3.0, n_elements=60, zzz=1)
    message = str(info.value)
    assert "did you mean" not in message            # nothing near 'zzz'
    own, forwarded = message.split("Accepted: its own parameters ")[1].split("; and ")
    assert "n_elements" in own and "settle" in own
    assert forwarded.startswith("aeolian_severity's options ")
    # Set by time_domain_check itself: not offered.
    assert "dampers" not in forwarded and "wind_speeds" not in forwarded
    assert "wind_curve" in forwarded and "strouhal" in forwarded


@pytest.mark.parametrize(("call", "option"), [
    (lambda: plc.severity.time_domain_check(DRAKE, 3.0, n_elements=60, dampers=()), "dampers"),
    (lambda: plc.sensors.sensor_count_study(SYS, [1], Q=np.eye(2), R=1.0, criterion="gramian"),
     "criterion"),
    (lambda: plc.recipe.estimator_count_study(_snapshots(), [2], n_sensors=3), "n_sensors"),
    (lambda: _estimate().recovery(100, estimate=None), "estimate"),
])
def test_an_option_the_function_sets_itself_is_refused_with_why(call, option):
    with pytest.raises(plc.InputError, match=rf"The '{option}' option cannot be passed to .*: "
                                             r"it sets it itself \("):
        call()


def test_a_valid_forwarded_option_still_reaches_the_target():
    rec = _estimate().recovery(100, hold=5)
    assert rec == _estimate().recovery(100, hold=5)
    assert plc.sensors.sensor_count_study(SYS, [1], Q=np.eye(2), R=1.0, n_steps=50,
                                          n_random=2).k == (1,)


def test_the_helper_returns_a_copy_and_takes_no_unknown_name():
    def inner(x, *, curve="cigre"):
        return x

    def outer(x, **options):
        return options

    given = {"curve": "ieee"}
    out = _validation.check_forwarded_options(outer, given, inner, set_here=("x",))
    assert out == given and out is not given
    with pytest.raises(plc.InputError, match="'x' option cannot be passed to .*outer"):
        _validation.check_forwarded_options(outer, {"x": 1}, inner, set_here=("x",))


# ------------------------------------------------- functions with many keywords, no **options
def _keyword_functions():
    """Every public function of the top level without ``**`` parameters, by name."""
    for name in plc.__all__:
        obj = getattr(plc, name)
        if not inspect.isfunction(obj):
            continue
        kinds = [p.kind for p in inspect.signature(obj).parameters.values()]
        if inspect.Parameter.VAR_KEYWORD not in kinds:
            yield name


@pytest.mark.parametrize("name", list(_keyword_functions()))
def test_every_public_function_refuses_a_misspelt_keyword_by_name(name):
    """Called with nothing but an unknown keyword, each public function refuses it by name,
    with every name it accepts (read from its own signature, independently of the check),
    before it binds its arguments (so before any work: no argument was given)."""
    function = getattr(plc, name)
    accepted = [p.name for p in inspect.signature(inspect.unwrap(function)).parameters.values()
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    with pytest.raises(plc.InputError) as info:
        function(no_such_keyword=1)
    assert str(info.value) == (f"{name} got an unknown keyword argument 'no_such_keyword'. "
                               f"Accepted: {', '.join(accepted)}.")


def test_run_closed_loop_names_a_misspelt_calibrate_and_the_nearest_name():
    """``calibrat=True`` escaped as Python's TypeError; now an InputError naming the keyword,
    the nearest accepted name and the accepted ones, before the span is meshed."""
    with pytest.raises(plc.InputError) as info:
        plc.run_closed_loop(DRAKE, plc.HarmonicForce(1.0, 9.0, 100.0), ROBOT,
                            sensors=[20, 50, 80], calibrat=True)
    message = str(info.value)
    assert message.startswith("run_closed_loop got an unknown keyword argument 'calibrat' "
                              "(did you mean 'calibrate'?). Accepted: model, force, robot, "
                              "limits, sensors, n_elements, ")
    accepted = list(inspect.signature(inspect.unwrap(plc.run_closed_loop)).parameters)
    assert message.endswith(", ".join(accepted[accepted.index("nominal"):]) + ".")
    assert not isinstance(info.value, TypeError)


def test_a_valid_keyword_still_reaches_the_decorated_function():
    assert plc.tension_at_temperature(DRAKE, 15.0, reference_temperature=15.0) == \
        pytest.approx(DRAKE.tension)
