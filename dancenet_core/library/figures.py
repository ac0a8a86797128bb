"""The figures a library's plan chooses from (`choreography.plan`): where in the library a figure may start and at
how many clip beats per song beat (`figure_states`), and what the plan weighs of each: how its joints move as it is
entered by a cut (`entry_steps`), its fastest joint (`figure_peaks`) and the stretches of beats before and after
each beat (`stretch_kinetics`).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..constants import WARP_RANGE
from .store import MotionLibrary
from .transitions import CUT_BLEND_S, beat_frames

# A figure plays every frame within WARP_RANGE of the speed it was captured at (in real time, whatever the beats):
# it is laid onto the song's beats at one of `RATIOS` clip beats per song beat, so that a clip danced at half or
# twice the song's tempo (or read an octave off) keeps its dancers' speed.
RATIOS = (1.0, 2.0, 0.5, 1.5, 2.0 / 3.0)
# A ratio is tried for a clip when it plays the clip's median beat within this much (log speed) beyond the range:
# the per-beat warp decides; ratios far off never fit and only cost time.
RATIO_MARGIN = 0.1
DEFAULT_BPM = 120.0  # the grid of a song without two tracked beats
START_DECIMALS = 6  # figure starts between two clip beats are rounded to this many decimals of a beat


@dataclass
class Grid:
    """The song's beats (seconds) over the part danced and its bars as (first beat, beats) pairs."""

    beats: np.ndarray
    bars: list[tuple[int, int]]
    meter: int


def figure_starts(library: MotionLibrary, meter: int, style: str | None, every: int | None = None) -> np.ndarray:
    """Beats where a figure may start: downbeats of clips in `meter`, every `meter` beats from the first downbeat of
    the others, and with `every` (fewer beats than `meter`: a figure that lays half a clip's bar on a song's bar)
    every `every` beats from each of those; only beats with one more of their clip after them, and only clips of
    `style` when the library has figures of it."""
    starts = np.zeros(len(library.beats), bool)
    for c in range(library.num_clips):
        idx = np.flatnonzero(library.beat_clip == c)
        if len(idx) < 2:
            continue
        if library.meter[c] == meter:
            starts[idx] = library.downbeat[idx]
        else:
            first = idx[np.argmax(library.downbeat[idx])] - idx[0]
            starts[idx[first::meter]] = True
    if every is not None and every < meter:
        downs = np.flatnonzero(starts)
        starts[np.minimum((downs[:, None] + every * np.arange(1, -(-meter // every))[None]).ravel(),
                          len(starts) - 1)] = True
    nxt = np.minimum(np.arange(len(starts)) + 1, len(starts) - 1)
    starts &= (library.beat_clip[nxt] == library.beat_clip) & (np.arange(len(starts)) + 1 < len(starts))
    if style:
        same = starts & np.isin(library.beat_clip, [c for c, s in enumerate(library.styles) if s == style])
        if same.any():
            starts = same
    return np.flatnonzero(starts)


def clip_ibi_s(library: MotionLibrary) -> np.ndarray:
    """[clips]: each clip's median beat interval (seconds; inf for a clip of one beat)."""
    ibi = np.full(library.num_clips, np.inf)
    for c in range(library.num_clips):
        b = library.beats[library.beat_clip == c]
        if len(b) > 1:
            ibi[c] = float(np.median(np.diff(b))) / library.fps
    return ibi


def figure_states(library: MotionLibrary, grid: Grid, style: str | None,
                  between_beats: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The figures the plan chooses from: (start beat, clip beats per song beat) pairs. Each clip is tried at the
    ratios (`RATIOS`) that play its median beat near its captured speed on the song's median beat, at least at its
    nearest; a ratio under 1 also from the clip beats where the song's bars fall within a clip's bar. Where a ratio
    lays a fraction of a beat on a bar (2/3 of a clip beat per song beat on a 4/4 bar: 8/3), the figure that carries
    on from one starts where it ends, between two clip beats (`START_DECIMALS`), so that a clip danced at that ratio
    is not cut every bar (`between_beats`)."""
    song_ibi = float(np.median(np.diff(grid.beats))) if len(grid.beats) > 1 else 60.0 / DEFAULT_BPM
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.abs(np.log(np.array(RATIOS)[None, :] * clip_ibi_s(library)[:, None] / song_ibi))
    off = np.nan_to_num(off, nan=np.inf, posinf=np.inf)
    tried = (off <= np.log1p(WARP_RANGE) + RATIO_MARGIN) | (off == off.min(axis=1, keepdims=True))
    in_range = off <= np.log1p(WARP_RANGE)
    starts, ratios = [], []
    for k, r in enumerate(RATIOS):
        span = r * grid.meter
        whole = abs(span - round(span)) < 1e-9
        every = int(round(span)) if r < 1 and whole else None
        s = figure_starts(library, grid.meter, style, every).astype(np.float64)
        if between_beats and not whole:  # a fraction of a beat a bar: the bars in between start between two
            # beats, for the clips the ratio plays within the speed limit (the others dance it only where nothing
            # else fits)
            turns = Fraction(span).limit_denominator(6).denominator
            fit = s[in_range[library.beat_clip[s.astype(np.int64)], k]]
            s = np.concatenate([s, (fit[:, None] + span * np.arange(1, turns)[None]).ravel()])
            s = s[np.ceil(s) < len(library.beats)]
            s = s[library.beat_clip[np.ceil(s).astype(np.int64)] == library.beat_clip[np.floor(s).astype(np.int64)]]
        s = np.round(s, START_DECIMALS)
        s = s[tried[library.beat_clip[np.floor(s).astype(np.int64)], k]]
        starts.append(s)
        ratios.append(np.full(len(s), r))
    return np.concatenate(starts), np.concatenate(ratios)


def within_clip(library: MotionLibrary, clip: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Whether figures of the clips `clip` that end at library beats `ends` (maybe between two) end within their
    clip: the clip goes on that far."""
    nb = len(library.beats)
    last = np.minimum(np.ceil(np.asarray(ends) - 1e-9).astype(np.int64), nb - 1)
    return (np.asarray(ends) <= nb - 1) & (library.beat_clip[last] == clip)


def beat_index(position: np.ndarray) -> np.ndarray:
    """The library beat at or before each (maybe fractional) beat position: its clip and energy."""
    return np.floor(np.asarray(position) + 10.0 ** -START_DECIMALS).astype(np.int64)


def nearest_beat(position: np.ndarray) -> np.ndarray:
    """The library beat nearest each beat position: whose boundary features stand for it."""
    return np.round(np.asarray(position)).astype(np.int64)


def figure_peaks(library: MotionLibrary, starts: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """[F]: each figure's fastest joint step over that joint's 99.9th percentile in the library
    (`MotionLibrary.peak_ratios`), at the library's own speed, over the clip beats it covers from `starts`."""
    frame = np.floor(library.beats).astype(np.int64)
    per_beat = np.maximum.reduceat(library.peak_ratios, np.minimum(frame, len(library.peak_ratios) - 1))
    first = beat_index(starts)
    last = np.minimum(np.ceil(starts + spans - 1e-9).astype(np.int64), len(per_beat)) - 1
    peak = np.zeros(len(starts))
    for k in range(int((last - first).max(initial=0)) + 1):
        at = np.minimum(first + k, len(per_beat) - 1)
        peak = np.where(first + k <= last, np.maximum(peak, per_beat[at]), peak)
    return peak


def entry_steps(library: MotionLibrary, starts: np.ndarray) -> np.ndarray:
    """[F]: for a figure entered by a cut at each start, its largest joint step (over that joint's 99th percentile in
    the library) from the frame before the cut to the end of the cut's blend, at the library's own speed."""
    ratio = library.step_ratios
    first = np.floor(beat_frames(library, starts)).astype(np.int64)
    clip = library.beat_clip[beat_index(starts)]
    lo = np.maximum(first - 1, library.clip_starts[clip])
    hi = np.minimum(first + int(round(CUT_BLEND_S * library.fps)) + 1, library.clip_starts[clip + 1] - 1)
    return np.array([ratio[a : b + 1].max() for a, b in zip(lo, hi, strict=True)])


def stretch_kinetics(library: MotionLibrary, beats: int) -> tuple[np.ndarray, np.ndarray]:
    """[B, 2 x body joints] twice: per beat of the library, each body joint's mean squared speed over the floor and
    up and down over the `beats` beats after it (within its clip) and over those before it, as standard deviations
    past the median of all such stretches in the library, less one (0 where within one, and for a stretch of under
    half as many beats, cut short by its clip's end or start)."""
    power = library.joint_motion[1]
    csum = np.concatenate([np.zeros((1, power.shape[1])), np.cumsum(power, axis=0, dtype=np.float64)])
    frame = np.floor(library.beats).astype(np.int64)
    clip = library.beat_clip
    index = np.arange(len(frame))
    first_beat = np.searchsorted(clip, clip, side="left")
    end_beat = np.searchsorted(clip, clip, side="right")  # one past the clip's last beat
    ahead, behind = np.minimum(index + beats, end_beat - 1), np.maximum(index - beats, first_beat)

    def mean(a: np.ndarray, b: np.ndarray, covered: np.ndarray) -> np.ndarray:
        power_mean = (csum[frame[b]] - csum[frame[a]]) / np.maximum(frame[b] - frame[a], 1)[:, None]
        return np.where((2 * covered >= beats)[:, None], power_mean, np.nan)

    after, before = mean(index, ahead, ahead - index), mean(behind, index, index - behind)
    centre, spread = np.nanmedian(after, axis=0), np.maximum(np.nanstd(after, axis=0), 1e-9)
    return tuple(np.nan_to_num(np.maximum((x - centre) / spread - 1.0, 0.0)).astype(np.float32)
                 for x in (after, before))
