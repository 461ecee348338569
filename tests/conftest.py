"""Shared test configuration.

Hypothesis runs derandomised by default (profile ``ci``: the same examples on every run, so CI is
never red by chance); ``--hypothesis-profile=random`` searches new examples (``max_examples`` x 5).
"""

from __future__ import annotations

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("random", derandomize=False, max_examples=500, print_blob=True)
settings.load_profile("ci")
