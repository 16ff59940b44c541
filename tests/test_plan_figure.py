"""The plan's figure draws what its legend says: the robot's target where its path ends, and the
nearest estimated antinode apart from it (on drake-300m they are 1.44 m, 0.46 loop, apart).

On the session's small lab result (tests/conftest.py): one figure drawn, under a second.
"""

import numpy as np

from powerline_control.scenario.summary import result_sections


def _vertical_lines(ax) -> list[float]:
    return sorted(float(line.get_xdata()[0]) for line in ax.get_lines()
                  if len(line.get_xdata()) == 2 and line.get_xdata()[0] == line.get_xdata()[1])


def test_the_plan_figure_marks_the_target_where_the_path_ends_and_the_antinode_apart(lab_result):
    plan = lab_result.plan
    section = next(s for s in result_sections(lab_result) if s["id"] == "plan")
    figure = next(f for f in section["figures"] if f["name"] == "robot_path")["draw"]()
    top, bottom = figure.axes[:2]
    labels = [t.get_text() for t in bottom.get_legend().get_texts()]
    assert labels == ["robot", "target (best parked position predicted)",
                      "nearest estimated antinode", "start"]
    path = next(line for line in bottom.get_lines() if line.get_label() == "robot")
    assert np.asarray(path.get_xdata())[-1] == np.float64(plan.choice.position)
    expected = sorted([plan.choice.position, plan.target.position])
    assert _vertical_lines(bottom) == expected and _vertical_lines(top) == expected
