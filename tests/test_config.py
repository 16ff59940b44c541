"""Scenario files: the schema, validation before computation, templates and the reference page."""

import dataclasses
import tomllib
from pathlib import Path

import pytest

from powerline_control import InputError
from powerline_control.scenario import (
    Scenario,
    default_scenario,
    load_scenario,
    scenario_reference,
    scenario_to_toml,
    shipped_scenarios,
)

ROOT = Path(__file__).resolve().parents[1]


def test_default_scenario_round_trips_through_toml():
    text = scenario_to_toml(default_scenario())
    assert load_scenario(text=text) == default_scenario()


@pytest.mark.parametrize("name", sorted(shipped_scenarios()))
def test_shipped_scenarios_load_by_name_and_round_trip(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    # The commented template is itself a valid scenario equal to the one it shows.
    assert load_scenario(text=scenario_to_toml(scenario)) == scenario


def test_shipped_scenarios_are_the_papers_cases_and_a_real_span():
    paper20, paper100 = load_scenario("paper-lab-20"), load_scenario("paper-lab-100")
    assert (paper20.model.n_elements, paper100.model.n_elements) == (20, 100)
    drake = load_scenario("drake-300m")
    span = drake.span.build()
    # drake-300m: Drake, 300 m, 20 % RTS (140.1 kN rated strength -> 28.02 kN), wind 3 m/s.
    assert span.length == 300.0
    assert span.tension == pytest.approx(0.20 * 140.1e3, rel=1e-3)
    assert drake.forcing.kind == "aeolian" and drake.forcing.wind_speed == 3.0
    # The absorber is tuned to the Strouhal frequency f = St V / d = 0.185 * 3 / 0.02814 m,
    # computed here from the formula (St 0.185 as in domain.md), not from the package.
    assert drake.forcing.load_frequency(span) == pytest.approx(0.185 * 3.0 / 0.02814, rel=1e-3)


def test_load_frequency_for_every_load_kind():
    span = default_scenario().span.build()
    harmonic = load_scenario(text="[forcing]\nfrequency = 31.0")
    random = load_scenario(text="[forcing]\nkind = 'random'\nbandwidth = 80.0")
    aeolian = load_scenario(text="[forcing]\nkind = 'aeolian'\nwind_speed = 2.0")
    assert harmonic.forcing.load_frequency(span) == 31.0
    assert random.forcing.load_frequency(span) == 40.0          # the centre of a 0-80 Hz band
    assert aeolian.forcing.load_frequency(span) == pytest.approx(0.185 * 2.0 / 0.0105)


def test_partial_file_keeps_other_defaults():
    scenario = load_scenario(text="[model]\nn_elements = 20\n[estimation]\nsensors = [3, 10]\n")
    assert scenario.model.n_elements == 20
    assert scenario.estimation.sensors == (3, 10)
    assert scenario.simulation == default_scenario().simulation


def test_template_comments_out_keys_the_preset_ignores():
    text = scenario_to_toml(default_scenario())
    active = tomllib.loads(text)["span"]
    # The lab preset fixes conductor, length and tension: the template must not show them as
    # settings (a setting shown must be one that is read).
    assert active == {"preset": "paper_lab"}
    assert "# conductor = " in text and "used only with preset" in text


def test_reference_page_is_generated_from_the_schema_and_committed():
    page = (ROOT / "docs" / "scenarios.md").read_text()
    assert page == scenario_reference(), (
        "docs/scenarios.md is stale: regenerate it with scenario_reference()")
    # Every key of every section is documented with its dotted name.
    for section in dataclasses.fields(Scenario):
        for key in dataclasses.fields(section.default_factory()):
            assert f"| `{section.name}.{key.name}` |" in page


# Bad input: (file text, dotted key the message must name, a phrase of what is allowed).
BAD = [
    ("[modle]\nn_elements = 20", "[modle]", "sections are"),
    ("[model]\nn_elemnts = 20", "model.n_elemnts", "keys of [model]"),
    ("[model]\nn_elements = 20.5", "model.n_elements", "integer"),
    ("[model]\nn_elements = 0", "model.n_elements", "2..20000"),
    ("[model]\nn_elements = 'many'", "model.n_elements", '"auto"'),
    ("[model]\nbc = 'glued'", "model.bc", '"pinned", "clamped"'),
    ("[model]\ndamping_ratio = 1.5", "model.damping_ratio", "< 1"),
    ("[simulation]\ndt = 'fast'", "simulation.dt", "a real number"),
    ("[simulation]\ndt = -0.001", "simulation.dt", "> 0"),
    ("[simulation]\nduration = 0.01", "simulation.duration", "at least 50 samples"),
    ("[simulation]\nduration = 3600.0\ndt = 1e-4", "simulation.duration", "samples"),
    ("[simulation]\nnoise_fraction = true", "simulation.noise_fraction", "a real number"),
    ("[forcing]\nkind = 'gust'", "forcing.kind", '"harmonic", "aeolian", "random"'),
    ("[forcing]\nposition = 4.0", "forcing.position", "0 < x < 3.66 m"),
    ("[forcing]\nfrequency = 600.0", "forcing.frequency", "Nyquist"),
    ("[forcing]\nkind = 'aeolian'\nfrequency = 20.0", "forcing.frequency", "forcing.kind"),
    ("[forcing]\nwind_speed = 3.0", "forcing.wind_speed", 'forcing.kind = "aeolian"'),
    ("[forcing]\nkind = 'aeolian'\nwind_speed = -1.0", "forcing.wind_speed", "> 0"),
    ("[identification]\nalpha = 'best'", "identification.alpha", '"auto"'),
    ("[identification]\ndelays = 0", "identification.delays", ">= 1"),
    ("[identification]\nrank = 2.5", "identification.rank", "integer"),
    ("[estimation]\nsensors = [5, 50, 500]", "estimation.sensors[2]", "1..99"),
    ("[estimation]\nsensors = [0, 5]", "estimation.sensors[0]", "supports"),
    ("[estimation]\nsensors = [5, 100]", "estimation.sensors[1]", "supports"),
    ("[estimation]\nsensors = [5, 5]", "estimation.sensors", "distinct"),
    ("[estimation]\nsensors = 5", "estimation.sensors", "list"),
    ("[estimation]\nsensors = [1.5]", "estimation.sensors[0]", "integer"),
    ("[estimation]\nsensor_positions = [1.0, 3.66]", "estimation.sensor_positions[1]",
     "0 < x < 3.66 m"),
    ("[estimation]\nsensors = [5]\nsensor_positions = [1.0]", "estimation.sensor_positions",
     "not both"),
    ("[estimation]\nsensors = [5]\nn_sensors = 3", "estimation.n_sensors", "Remove one"),
    ("[model]\nn_elements = 'auto'\n[estimation]\nsensors = [5]", "estimation.sensors",
     "sensor_positions"),
    ("[robot]\nstart = 10.0", "robot.start", "0 < x < 3.66 m"),
    ("[robot]\nstart = 0.0", "robot.start", "0 < x < 3.66 m"),
    ("[robot]\nv_max = 0", "robot.v_max", "> 0"),
    ("[robot]\nsuspended_mass = -1.0", "robot.suspended_mass", "> 0"),
    ("[span]\npreset = 'paper_lab'\nconductor = 'drake'", "span.conductor", "span.preset"),
    ("[span]\nlength = 300.0", "span.length", 'span.preset = "conductor"'),
    ("[span]\npreset = 'conductor'\nconductor = 'unobtainium'", "span.conductor", "drake"),
    ("[span]\npreset = 'conductor'\nrts_fraction = -0.2", "span.rts_fraction", "> 0"),
    ("[span]\npreset = 'conductor'\ntension = -28000.0", "span.tension", "> 0 N"),
    ("[span]\npreset = 'conductor'\ntension = 2e5", "span.tension", "rated strength"),
    ("[span]\npreset = 'conductor'\ntension = 2e4\nrts_fraction = 0.2", "span.tension",
     "not both"),
    ("[span]\npreset = 'conductor'\nlength = 300.0\n[robot]\nstart = 301.0", "robot.start",
     "0 < x < 300 m"),
    ("[severity]\nwind_speeds = [1.0, 2.0]", "severity.wind_speeds", "severity.enabled"),
    ("[severity]\nenabled = 'yes'", "severity.enabled", "true or false"),
    ("[scenario]\nname = 3", "scenario.name", "a string"),
    ("robot = 3", "[robot]", "table"),
    ("[model\n", "not valid TOML", "line 1"),
]


@pytest.mark.parametrize(("text", "key", "allowed"), BAD)
def test_bad_scenarios_name_the_file_the_dotted_key_and_what_is_allowed(text, key, allowed):
    with pytest.raises(InputError) as caught:
        load_scenario(text=text, source="my.toml")
    message = str(caught.value)
    assert message.startswith("my.toml: ")
    assert key in message
    assert allowed in message


def test_missing_file_and_unknown_name_are_clear_errors(tmp_path):
    with pytest.raises(InputError, match="Cannot read the scenario file .*nope.toml"):
        load_scenario(tmp_path / "nope.toml")
    with pytest.raises(InputError, match="drake-300m"):  # lists the shipped names
        load_scenario("drake-301m")


@pytest.mark.parametrize(("kwargs", "parameter"), [
    ({"text": float("nan")}, "'text'"),          # tomllib raised AttributeError
    ({"text": b"[model]\nn_elements = 20"}, "'text'"),  # bytes: decode it first
    ({"text": ["[model]"]}, "'text'"),
    ({"path": 3}, "'path'"),                     # Path(3) raised TypeError
    ({"path": 2.5}, "'path'"),
    ({"text": "", "source": 3}, "'source'"),
])
def test_wrong_argument_types_are_input_errors(kwargs, parameter):
    with pytest.raises(InputError, match=parameter):
        load_scenario(**kwargs)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_or_a_huge_file_is_not_read(tmp_path):
    with pytest.raises(InputError, match="'/dev/zero' is not a regular file"):
        load_scenario("/dev/zero")  # read_text() never returned
    with pytest.raises(InputError, match="is not a regular file"):
        load_scenario(tmp_path)
    big = tmp_path / "big.toml"
    big.write_text("# padding\n" * 100_001)  # 10 bytes x 100001 lines: just over 1 MB of TOML
    with pytest.raises(InputError, match="1000010 bytes, over the 1000000"):
        load_scenario(big)


def test_file_errors_name_the_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[robot]\nstart = -1.0\n")
    with pytest.raises(InputError, match=r"bad\.toml: robot\.start = -1\.0"):
        load_scenario(path)


def test_template_of_a_scenario_with_listed_sensors_and_a_tension_loads_back():
    # n_sensors and rts_fraction are superseded by listed sensors and a tension: the template
    # writes them commented out, so it does not contradict itself.
    scenario = load_scenario(text="[estimation]\nsensors = [3, 7]\n[span]\npreset = 'conductor'"
                                  "\ntension = 25000.0\n")
    text = scenario_to_toml(scenario)
    assert "# n_sensors = 3    # unset because the sensors are listed" in text
    assert load_scenario(text=text) == scenario
    assert scenario.span.build().tension == 25000.0


# --------------------------------------------------------- escaping: text round-trips through TOML
@pytest.mark.parametrize(("name", "written"), [
    ('the "B" line', r'"the \"B\" line"'),
    (r"C:\new\tests", r'"C:\\new\\tests"'),
    (r"C:\runs\b", r'"C:\\runs\\b"'),           # reloaded as 'C:\runs\x08' before
    ("tab\there\nnew line\x00\x7f", r'"tab\there\nnew line\u0000\u007F"'),
    ("é ü 😀", '"é ü 😀"'),                     # Unicode is written as is
])
def test_scenario_to_toml_escapes_every_string_and_reloads_it(tmp_path, name, written):
    scenario = dataclasses.replace(default_scenario(), scenario=dataclasses.replace(
        default_scenario().scenario, name=name))
    text = scenario_to_toml(scenario)
    assert f"name = {written}\n" in text
    assert load_scenario(text=text).name == name
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    assert load_scenario(path) == scenario


def test_a_string_no_file_can_hold_is_refused_by_the_writer():
    scenario = dataclasses.replace(default_scenario(), scenario=dataclasses.replace(
        default_scenario().scenario, description="lone \ud800"))
    with pytest.raises(InputError, match="lone surrogate"):
        scenario_to_toml(scenario)


def test_a_scenario_file_with_a_byte_order_mark_and_crlf_loads(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b"\xef\xbb\xbf[model]\r\nn_elements = 20\r\n")   # Notepad's "UTF-8"
    assert load_scenario(path).model.n_elements == 20
    assert load_scenario(text="\ufeff[model]\nn_elements = 21").model.n_elements == 21
