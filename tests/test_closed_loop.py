"""The closed loop: the robot finds the antinode from three sensors and the line vibrates less."""

import numpy as np
import pytest

import powerline_control as plc
from powerline_control.closed_loop import run_closed_loop

LAB = plc.Span.paper_lab()


@pytest.fixture(scope="module")
def result():
    # 40 elements keep the test quick; forced at 24 Hz, next to mode 3 (24.5 Hz), whose nodes are
    # at L/3 and 2L/3. The robot starts at 1.2 m, next to the node at L/3 = 1.22 m: the worst place.
    f3 = plc.LineModel(LAB, 40).natural_frequencies(3)[2]
    robot = plc.MDR.tuned(1.2, body_mass=0.02, suspended_mass=0.05, frequency=f3, damping_ratio=0.1)
    limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
    return run_closed_loop(
        LAB,
        plc.HarmonicForce(1.0, 24.0, 0.5),
        robot,
        limits,
        sensors=[6, 16, 28],
        n_elements=40,
        duration=6.0,
        calibration=2.0,
        obstacles=[(2.6, 2.8)],
        seed=1,
    )


def test_line_vibrates_less_than_with_the_robot_parked(result):
    # A tuned absorber at a node of the driven mode does nothing to it; at an antinode it damps
    # it. Measured: about 7x less RMS displacement; 3x leaves room for seeds and model changes.
    assert result.vibration_reduction > 3.0


def test_robot_ends_in_the_loop_whose_antinode_it_was_sent_to(result):
    # Mode 3's loops are [0, L/3], [L/3, 2L/3], [2L/3, L]; the robot starts at the first node, so
    # it must settle inside one loop, away from the nodes (the absorber shifts the antinode a bit).
    final = result.robot_position[-1]
    distance_to_node = np.min(np.abs(final - LAB.length * np.array([1 / 3, 2 / 3])))
    assert distance_to_node > 0.25 * LAB.length / 3


def test_robot_respects_its_limits_and_the_obstacle(result):
    # Constant acceleration per period: sampled velocity is exact, so the limit holds at samples.
    assert np.abs(result.robot_velocity).max() <= 0.5 + 1e-9
    accel = np.diff(result.robot_velocity) / np.diff(result.t)
    assert np.abs(accel).max() <= 1.0 + 1e-6
    assert not np.any((result.robot_position > 2.6) & (result.robot_position < 2.8))


def test_estimate_tracks_the_true_field_after_calibration(result):
    after = result.t > result.calibration_time + 0.5
    error = result.estimated_field[:, after] - result.displacement[:, after]
    relative = np.sqrt(np.mean(error**2)) / np.sqrt(np.mean(result.displacement[:, after] ** 2))
    # The model was identified with the robot parked; moving it changes the line, so the
    # estimate is not perfect. Measured ~10-20 %; 50 % still locates the loops.
    assert relative < 0.5


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(sensors=[]), "sensors"),
        (dict(sensors=[50]), "sensors"),
        (dict(calibration=10.0), "calibration"),
        (dict(control_period=0.0015), "control_period"),
    ],
)
def test_bad_arguments(kwargs, name):
    args = {"sensors": [5, 10], "n_elements": 20, "duration": 3.0, "calibration": 1.0, **kwargs}
    with pytest.raises(plc.InputError, match=name):
        run_closed_loop(LAB, plc.HarmonicForce(1.0, 24.0, 0.5), plc.MDR(1.2, 0.02), **args)
