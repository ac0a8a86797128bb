"""Song -> dances: the one entry point the command line, the Blender add-on and batch mode share.

`generate_dance(request)` checks the request (and lets its engine load what it needs) before a second of music
analysis, analyses the music (cached) and reads the song's form; the engine the request names (`engines/`) dances
the part, sections with settings of their own are danced anew by it, and the steps of `shaping/` shape the takes
in their one order (its docstring): the song's returning sections danced again, the foot contacts and the figure
list following (`shaping.takes.with_repeats`). `shaping.takes.shape_takes` then turns the takes into what is
written or keyed (the frame rate, the kept frames of a continued dance, the root motion), for the command line
and the add-on alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .constants import MIN_PART_S
from .engines import Engine, Takes, get_engine
from .environment import one_blas_thread
from .errors import DanceNetError, GenerationCancelled
from .licence import analysis_part, licence_block
from .motion import Motion
from .music.features import MusicAnalysis, analyze_music
from .music.form import Section, SongForm, song_form
from .music.weightfree import analyze_music_weightfree
from .progress import StageProgress
from .request import DEFAULT_ENGINE, MAX_SEED, MAX_TAKES, DanceRequest
from .shaping.continuation import DIFFERENCES
from .shaping.figures import danced_figures, spliced
from .shaping.repeats import JOIN_BLEND_S, carry_on
from .shaping.takes import with_repeats


@dataclass
class GenerationResult:
    motions: list[Motion]  # per take, at the engine's frame rate, as danced (see `shaping.takes.shape_takes`)
    beat_times: np.ndarray
    downbeat_times: np.ndarray
    tempo_bpm: float
    duration_s: float
    style: str
    style_probabilities: dict[str, float]
    timings: dict[str, float] = field(default_factory=dict)
    contacts: list[np.ndarray] = field(default_factory=list)  # [T, 2] predicted foot contacts per take
    start_s: float = 0.0  # where the dance starts in the song; beat times count from there
    details: list[dict] = field(default_factory=list)  # per take, the engine's report on it (`Takes.details`)
    form: SongForm | None = None  # the song's sections (times in the song, not the part)
    licence: dict = field(default_factory=dict)  # the parts that made it and their terms (`licence.licence_block`)


def check_request(request: DanceRequest) -> Engine:
    """Reject a bad request in a second, before a minute of music analysis: its own checks, then its engine's
    (which loads the weights, so a bad file or an unknown style is reported now). Returns the engine."""
    request.check()
    engine = get_engine(request.engine)
    engine.check(request)
    for o in request.sections:
        if o.style is not None:
            engine.check(replace(request, style=o.style))  # a style the engine lacks, said now
    return engine


def available_styles(engine: str = DEFAULT_ENGINE, weights: str | None = None) -> list[str]:
    """The styles an engine dances (the default engine's, with its shipped weights, by default)."""
    return get_engine(engine).styles(DanceRequest(Path(), engine=engine, weights=weights))  # no song is read


@one_blas_thread
def generate_dance(request: DanceRequest, progress: StageProgress | None = None,
                   should_cancel: Callable[[], bool] | None = None) -> GenerationResult:
    """The request's takes for its song, or for the part from `start_s` to `end_s` seconds, with the beats
    of that part (counted from its start). Same request, same seed: the same dance, bit for bit."""
    engine = check_request(request)
    report = progress or (lambda _s, _f: None)
    cancelled = should_cancel or (lambda: False)

    t = time.perf_counter()
    report("analysing music", 0.0)
    analysis = analyze(request.song, request.commercial, progress=lambda f: report("analysing music", f))
    analysis_s = time.perf_counter() - t
    if cancelled():
        raise GenerationCancelled
    start, end = request.part(analysis.duration_s)
    form = song_form(analysis)
    for o in request.sections:
        section_named(form, o.section, (start, end))  # a section the song lacks, said before the dancing
    if request.redo_section is not None:  # one section of a kept dance danced anew
        takes = _redo_section(engine, form, analysis, request, (start, end), report, cancelled)
    else:  # the engine's dance, its sections of their own danced anew, then the repeats of the song's sections
        takes = engine.dance(request, analysis, report, cancelled)
        takes = _with_sections(engine, takes, form, analysis, request, (start, end), report, cancelled)
        t = time.perf_counter()
        _with_repeats(takes, form, start, request)
        takes.timings["returns_s"] = time.perf_counter() - t
    report("done", 1.0)

    def within(times: np.ndarray) -> np.ndarray:
        return times[(times >= start) & (times < end)] - start

    return GenerationResult(
        motions=takes.motions, beat_times=within(analysis.beat_times),
        downbeat_times=within(analysis.downbeat_times), tempo_bpm=analysis.tempo_bpm, duration_s=end - start,
        style=takes.style, style_probabilities=takes.style_probabilities,
        timings={"analysis_s": analysis_s, **takes.timings}, contacts=takes.contacts, start_s=start,
        details=takes.details, form=form,
        licence=licence_block([analysis_part(request.commercial), *takes.parts], request.commercial),
    )


def analyze(song: Path, commercial: bool, progress: Callable[[float], None] | None = None) -> MusicAnalysis:
    """The song's analysis (cached): the default one (madmom's networks), or in the commercial mode the one from
    signal processing alone (`music.weightfree`)."""
    if commercial:
        return analyze_music_weightfree(song, progress=progress)
    return analyze_music(song, progress=progress)


def section_named(form: SongForm, name: str, part: tuple[float, float]) -> Section:
    """The section of the song's form called `name` (A2) that starts within the danced part, or a one-line
    error listing those there are."""
    start, end = part
    inside = [s for s in form.sections if start <= s.start_s < end - MIN_PART_S]
    found = next((s for s in inside if s.name == name), None)
    if found is None:
        raise DanceNetError(f"the danced part of the song has no section '{name}'; its sections are "
                            f"{', '.join(s.name for s in inside)} (`dancenet analyze SONG` lists them)")
    return found


def _section_anew(engine: Engine, analysis: MusicAnalysis, request: DanceRequest, dance: Motion, section: Section,
                  part: tuple[float, float], report: StageProgress, cancelled: Callable[[], bool]) -> Takes:
    """One take: `dance` (of the part) with `section` danced anew by `request`, `dance` kept before the section
    (where there are frames enough to continue from), the new dance run on past the section's end to crossfade
    into the rest of `dance`, carried on from where it ends; its contacts those of the new frames."""
    start, end = part
    at_s = section.start_s - start
    kept = dict(continue_from=dance, at_s=at_s) if at_s * dance.fps > DIFFERENCES else {}
    sub = replace(request, takes=1, end_s=min(end, section.end_s + JOIN_BLEND_S), sections=(), returns="anew",
                  redo_section=None, **kept)
    takes = engine.dance(sub, analysis, report, cancelled)
    danced = takes.motions[0]
    leave = min(round((section.end_s - start) * danced.fps), danced.num_frames)
    takes.motions = [carry_on(danced, dance.resampled(danced.fps), leave)]
    takes.contacts = [c[:leave] for c in takes.contacts]
    return takes


def _redo_section(engine: Engine, form: SongForm, analysis: MusicAnalysis, request: DanceRequest,
                  part: tuple[float, float], report: StageProgress, cancelled: Callable[[], bool]) -> Takes:
    """`request.continue_from` with the section `request.redo_section` danced anew (new frames from its start to
    its end, then the kept dance carried on from where they end)."""
    assert request.redo_section is not None and request.continue_from is not None
    section = section_named(form, request.redo_section, part)
    takes = _section_anew(engine, analysis, request, request.continue_from, section, part, report, cancelled)
    takes.contacts = []  # the kept dance has none
    for details in takes.details:  # a library take lists the section's figures (the kept dance's are not known)
        if "danced_figures" in details:
            rows = spliced([], details["danced_figures"], section.start_s, section.end_s)
            details["danced_figures"] = danced_figures(rows, [], section.end_s, takes.motions[0].fps)
    return takes


def _with_sections(engine: Engine, takes: Takes, form: SongForm, analysis: MusicAnalysis, request: DanceRequest,
                   part: tuple[float, float], report: StageProgress, cancelled: Callable[[], bool]) -> Takes:
    """The takes with each section that has a style or an energy of its own (`request.sections`) danced anew
    with them, a new seed for each, the dance after it carried on."""
    for i, o in enumerate(o for o in request.sections if o.redances):
        section = section_named(form, o.section, part)
        for k, motion in enumerate(takes.motions):
            sub = replace(request, style=o.style or request.style, energy=o.energy or request.energy,
                          seed=(request.seed + 1 + MAX_TAKES * i + k) % (MAX_SEED + 1))
            new = _section_anew(engine, analysis, sub, motion, section, part, report, cancelled)
            takes.parts = list(dict.fromkeys([*takes.parts, *new.parts]))
            takes.motions[k] = new.motions[0]
            if k < len(takes.details) and new.details and "danced_figures" in new.details[0]:
                takes.details[k]["danced_figures"] = spliced(takes.details[k]["danced_figures"],
                                                             new.details[0]["danced_figures"], section.start_s,
                                                             section.end_s)
            if k < len(takes.contacts) and new.contacts:
                done = len(new.contacts[0])
                takes.contacts[k] = np.concatenate([new.contacts[0], takes.contacts[k][done:]])
    return takes


def _with_repeats(takes: Takes, form: SongForm, start_s: float, request: DanceRequest) -> None:
    """Each take with the song's returning sections danced again (`shaping.takes.with_repeats`), in place."""
    for k, motion in enumerate(takes.motions):
        details = takes.details[k] if k < len(takes.details) else {}
        contacts = takes.contacts[k] if k < len(takes.contacts) else None
        takes.motions[k], contacts, figures = with_repeats(motion, contacts, details.get("danced_figures"), form,
                                                           start_s, request)
        if contacts is not None:
            takes.contacts[k] = contacts
        if figures is not None:
            details["danced_figures"] = figures
