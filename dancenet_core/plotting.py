"""Matplotlib for the figures (evaluation plots, the data viewer), loaded on first use: it is heavy (about
half a second) and nothing that dances needs it."""

from __future__ import annotations

from types import ModuleType


def pyplot() -> ModuleType:
    """`matplotlib.pyplot` drawing off-screen (Agg), so figures work without a display."""
    import matplotlib  # heavy and optional: only figures load it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
