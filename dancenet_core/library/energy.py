"""How fast a library's clips move, and a plan's dance: the measure `choreography.plan_at_clips_energy` matches."""

from __future__ import annotations

import numpy as np

from .store import MotionLibrary


def clips_energy(library: MotionLibrary) -> float:
    """The clips' mean joint speed (m/s), every frame alike: `MotionLibrary.energy` weighted by each beat's length."""
    last = np.r_[library.beat_clip[1:] != library.beat_clip[:-1], True]
    ends = np.where(last, library.clip_starts[library.beat_clip + 1], np.r_[library.beats[1:], 0.0])
    length = np.maximum(ends - library.beats, 0.0)
    return float((library.energy * length).sum() / max(length.sum(), 1e-9))


def dance_energy(library: MotionLibrary, beats: np.ndarray, song_bars: list[tuple[int, int]],
                 bars: list[tuple[float, float]]) -> float:
    """The mean joint speed (m/s) of the clip beats a plan (`bars`: each bar's start and clip beats per song beat)
    lays on the song's bars (`song_bars`: first beat and beats, of `beats` in seconds), each weighted by its length."""
    csum = np.concatenate([[0.0], np.cumsum(library.energy, dtype=np.float64)])
    beat = np.arange(len(csum))
    total = weight = 0.0
    for (start, ratio), (a, n) in zip(bars, song_bars, strict=True):
        span = max(ratio * n, 1e-9)
        mean = (np.interp(min(start + span, len(csum) - 1), beat, csum) - np.interp(start, beat, csum)) / span
        seconds = beats[a + n] - beats[a]
        total, weight = total + mean * seconds, weight + seconds
    return total / max(weight, 1e-9)
