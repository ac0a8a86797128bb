"""The engine `library` (`dancenet generate SONG --engine library --library FOLDER`): dances cut from a built motion
library (`dancenet library build FOLDER`) on the song's beats; see `choreography.py`."""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..constants import MIN_PART_S
from ..engines import Takes
from ..engines.styles import check_style, choose_style, load_style_model, meter_of, style_by_tempo
from ..errors import DanceNetError, GenerationCancelled
from ..motion import Motion
from ..music.features import MusicAnalysis
from ..progress import StageProgress
from ..request import DanceRequest
from .choreography import choreograph
from .match import MatchModel
from .store import MotionLibrary, library_path, load_built, load_default

# The style of a dance any clip may dance: what a dance from unnamed styles is called, and a style one may ask for
# (a take's record asks for it again when it is continued).
ANY_STYLE = "any"


@lru_cache(maxsize=2)
def _load(path: Path, key: Path) -> MotionLibrary:
    """The built library (cached per built file: a rebuilt folder has a new key)."""
    return load_built(path)


@lru_cache(maxsize=1)
def _load_default() -> MotionLibrary:
    return load_default()


@lru_cache(maxsize=1)
def _load_match() -> MatchModel:
    """The learned match of music and movement: what keeps a library without style labels to the song's style."""
    return MatchModel.load()


class LibraryEngine:
    """Reads `request.library`, a folder of clips built with `dancenet library build`, or without one the shipped
    library of CMU's dance clips (`store.DEFAULT_LIBRARY`)."""

    name = "library"

    def library(self, request: DanceRequest) -> MotionLibrary:
        if request.library is None:  # the shipped CMU library
            return _load_default()
        folder = Path(request.library)
        return _load(folder, library_path(folder) if folder.is_dir() else folder)

    def styles(self, request: DanceRequest) -> list[str]:
        return sorted({s for s in self.library(request).styles if s})

    def check(self, request: DanceRequest) -> None:
        """The library is built and loads; the style is one of its clips'; a dance continued is of its skeleton."""
        library = self.library(request)
        styles = self.styles(request)
        if request.style not in ("auto", ANY_STYLE):
            check_style(request.style, styles)
        kept = request.continue_from
        if kept is not None and kept.skeleton.names != library.skeleton.names:
            raise DanceNetError("only a dance of the library's skeleton (DanceNet's 55 joints) can be continued")

    def dance(self, request: DanceRequest, analysis: MusicAnalysis, progress: StageProgress,
              should_cancel: Callable[[], bool]) -> Takes:
        """A figure per bar, time-warped to the song's beats (no foot model: the frames are real capture, and the
        model, trained on DanceNet's dances, slid them more: docs/experiments.md). A library whose clips name no
        style is kept to the song's style by the learned match of music and movement (`match.py`)."""
        timings: dict[str, float] = {}
        t = time.perf_counter()
        library = self.library(request)
        styles = self.styles(request)
        if request.commercial:  # no classifier: the user's style, else the one whose tempo and meter fit the song's
            chosen, probs = _style_without_classifier(request.style, analysis, styles), {}
        else:
            chosen, probs = _style_by_classifier(request.style, analysis, styles)
        timings["style_s"] = time.perf_counter() - t
        if should_cancel():
            raise GenerationCancelled
        t = time.perf_counter()
        progress("dancing", 0.0)
        start, end = request.part(analysis.duration_s)
        kept = _kept(request, library.fps, end - start)
        match = _load_match() if library.unlabelled and not request.commercial else None
        dances = choreograph(library, analysis, request.seed, start + (0.0 if kept is None else kept.duration), end,
                             request.takes, chosen or None, kept=kept, match=match)
        timings["choreography_s"] = time.perf_counter() - t
        progress("dancing", 1.0)
        motions = [d.motion if kept is None else _after(kept, d.motion) for d in dances]
        parts = ["shipped_library" if request.library is None else "own_library",
                 *(["style_classifier"] if probs else []), *(["learned_match"] if match is not None else []),
                 *(["chosen_style"] if request.style not in ("auto", ANY_STYLE) else []),
                 *(["style_by_tempo"] if request.commercial and request.style == "auto" else [])]
        return Takes(motions, chosen or ANY_STYLE, probs, timings=timings,
                     details=[d.report.summary() | {"danced_figures": d.report.figures} for d in dances], parts=parts)


def _style_by_classifier(requested: str, analysis: MusicAnalysis, styles: list[str]) -> tuple[str, dict]:
    """The user's style, or the classifier's among the library's styles it can tell."""
    heard = set(styles) & set(load_style_model().styles)  # styles the music classifier can tell
    if requested == ANY_STYLE or (requested == "auto" and not heard):
        return "", {}  # asked for, or a library of styles no classifier knows: every clip may dance
    return choose_style(requested, analysis, sorted(heard) if requested == "auto" else styles)


def _style_without_classifier(requested: str, analysis: MusicAnalysis, styles: list[str]) -> str:
    """The user's style, or the library's style whose dance-sport tempo and meter fit the song's ("" when none does:
    every clip may dance, the plan led by the music's energy and tempo alone)."""
    if requested == ANY_STYLE:
        return ""
    if requested != "auto":
        return requested
    return style_by_tempo(analysis.tempo_bpm, meter_of(analysis), styles)


def _after(kept: Motion, new: Motion) -> Motion:
    """The kept frames, then the new ones (the whole part, as `Takes` has it)."""
    return Motion(np.concatenate([kept.rotations, new.rotations]),
                  np.concatenate([kept.root_positions, new.root_positions]), new.fps, new.skeleton)


def _kept(request: DanceRequest, fps: float, part_s: float) -> Motion | None:
    """The continued dance's frames before `request.at_s` at the library's frame rate (its duration: where the new
    dancing starts), or a one-line error when there is too little of it before, or of the part after."""
    if request.continue_from is None:
        return None
    kept = request.continue_from.resampled(fps)
    k = min(int(round(request.at_s * fps)), kept.num_frames)
    if k < 2:
        raise DanceNetError(f"the dance can be continued from {2 / fps:g} s to its end ({kept.duration:.2f} s), "
                            f"got {request.at_s}")
    if part_s - k / fps < MIN_PART_S:
        raise DanceNetError(f"continuing at {request.at_s:g} s leaves less than {MIN_PART_S:g} s of the part of the "
                            f"song to dance ({part_s:.1f} s)")
    return kept[:k]
