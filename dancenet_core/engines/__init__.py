"""Engines: what turns a song's analysis into dances. The command line and the add-on choose one by name
(`DanceRequest.engine`) and know nothing else about it.

An engine is an object with a `name`, a `check(request)` that loads what it needs and rejects what it cannot
dance (a one-line DanceNetError, before the music is analysed), `styles(request)` (the styles it dances, for
`--style` and the add-on's list), and `dance(request, analysis, progress, should_cancel) -> Takes`. An engine
that needs more than the request's common fields reads its own (e.g. `request.library`, a folder of clips).
`ENGINES` names each engine's factory as "module:attribute", imported only when the engine is chosen, so
listing engines loads none of them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Protocol

import numpy as np

from ..errors import DanceNetError
from ..motion import Motion
from ..music.features import MusicAnalysis
from ..progress import StageProgress
from ..request import DanceRequest

# name -> "module:attribute" of a class or function that makes the engine (no arguments).
ENGINES: dict[str, str] = {
    "dancenet": "dancenet_core.engines.dancenet:DanceNetEngine",
    "library": "dancenet_core.library.engine:LibraryEngine",
}


@dataclass
class Takes:
    """What an engine made for the part of the song `request.part` gives: one Motion per take, travelling (as
    danced), at the engine's own frame rate, starting at the part's start; `shaping.takes.shape_takes` turns them
    into what is written or keyed."""

    motions: list[Motion]
    style: str
    style_probabilities: dict[str, float] = field(default_factory=dict)  # empty when the user chose the style
    contacts: list[np.ndarray] = field(default_factory=list)  # [T, 2] foot contacts per take, if the engine has them
    timings: dict[str, float] = field(default_factory=dict)  # seconds per stage, for the summary
    # Per take, what the engine reports about it for the summary (the library engine: how much is copied), or empty.
    details: list[dict] = field(default_factory=list)
    parts: list[str] = field(default_factory=list)  # what made them beside the music analysis (`licence.PARTS`)


class Engine(Protocol):
    """What the command line and the add-on call; see the module's docstring."""

    name: str

    def check(self, request: DanceRequest) -> None: ...

    def styles(self, request: DanceRequest) -> list[str]: ...

    def dance(self, request: DanceRequest, analysis: MusicAnalysis, progress: StageProgress,
              should_cancel: Callable[[], bool]) -> Takes: ...


def engine_names() -> list[str]:
    return list(ENGINES)


@cache
def get_engine(name: str) -> Engine:
    """The engine called `name` (made once per process), or a one-line error listing those there are."""
    if name not in ENGINES:
        raise DanceNetError(f"unknown engine '{name}'; choose one of: {', '.join(ENGINES)}")
    module, attribute = ENGINES[name].split(":")
    return getattr(importlib.import_module(module), attribute)()
