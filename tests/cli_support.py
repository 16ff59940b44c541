"""What the command-line tests share: the command on this checkout, and two small scenarios.

The command is the installed ``powerline-control`` script beside this Python when there is one
(what a user runs), else ``python -m powerline_control``; it must import this checkout's package,
so the checkout is put first on its PYTHONPATH.
"""

import os
import subprocess
import sys
from pathlib import Path

import powerline_control as plc

_ENTRY = Path(sys.executable).with_name("powerline-control")
COMMAND = [str(_ENTRY)] if _ENTRY.exists() else [sys.executable, "-m", "powerline_control"]

# A 12-element lab span: every stage in a few seconds.
TINY = """\
[scenario]
name = "tiny"
description = "A 12-element lab span for the command's tests."
[model]
n_elements = 12
[simulation]
duration = 2.5
[estimation]
n_sensors = 2
[robot]
start = 1.0
closed_loop = 1.5
"""

# The same with 14 elements (its sensor and antinode positions differ from TINY's).
SMALL = """\
[scenario]
name = "small"
[model]
n_elements = 14
[simulation]
duration = 2.5
[estimation]
n_sensors = 2
[robot]
start = 1.0
closed_loop = 1.5
"""


def run_cli(*args, cwd=None, timeout=600):
    """Run the command with ``args``; the completed process, its output captured as text."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(plc.__file__).parents[1])] + env.get("PYTHONPATH", "").split(os.pathsep))
    return subprocess.run(COMMAND + [str(a) for a in args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=timeout)
