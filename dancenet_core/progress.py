"""The two progress callbacks long jobs report through (one home, so every caller passes the same kind)."""

from __future__ import annotations

from collections.abc import Callable

# Fraction done, 0 to 1, of one job (music analysis, sampling, rendering).
Progress = Callable[[float], None]
# The stage's name and its fraction done (generation: analysing music, dancing, cleaning feet).
StageProgress = Callable[[str, float], None]
