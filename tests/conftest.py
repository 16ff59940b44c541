"""Results several test modules read: computed once per session, never modified (they are frozen).

``lab_result``: a 14-element lab span through every stage the report draws (sensor count,
closed loop, severity), about 14 s on 2 cores. Its 1.5 s closed loop is too short for the robot to
reach the best position, which the closed loop says (ReachWarning): right, and not what the
tests that read it are about.

``closed_loop_call``: what a scenario stage passes to ``run_closed_loop``, captured by a stand-in
that stops the stage there (the keyword arguments, a dict filled when the stage calls it).
"""

import warnings

import pytest
from cli_support import SMALL

#: The scenario of ``lab_result``: the command tests' small lab span with severity enabled.
SMALL_ALL = SMALL + "[severity]\nenabled = true\n"


@pytest.fixture(scope="session")
def lab_result():
    from powerline_control.errors import ReachWarning
    from powerline_control.scenario import load_scenario
    from powerline_control.scenario.pipeline import run_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ReachWarning)
        result = run_scenario(load_scenario(text=SMALL_ALL, source="small"))
    assert result.ok
    return result


@pytest.fixture
def closed_loop_call(monkeypatch):
    from powerline_control.closed_loop import loop

    seen = {}

    def stand_in(*args, **kwargs):
        seen.update(kwargs)
        raise RuntimeError("stop")

    monkeypatch.setattr(loop, "run_closed_loop", stand_in)
    monkeypatch.setattr("powerline_control.closed_loop.run_closed_loop", stand_in)
    return seen
