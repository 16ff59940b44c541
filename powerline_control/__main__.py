"""``python -m powerline_control`` runs the ``powerline-control`` command."""

import sys

from .cli import main

sys.exit(main())
