"""Shared pytest setup: a non-interactive matplotlib backend for figure-making code and tests."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
