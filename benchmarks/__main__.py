"""``python -m benchmarks [--quick] [--json PATH]``: the same as ``python benchmarks/run.py``."""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from run import main  # noqa: E402  (run pins BLAS before importing numpy)

main()
