"""Cuts are made where the dancers are calm (no joint's step at a transition past the capture's 99th
percentile): a cut into a figure whose joints, as the warp plays them, step past `CALM_LIMIT` of their 99th
percentile in the library costs steeply, so the plan cuts into calmer figures where it has them."""

from __future__ import annotations

import numpy as np
from test_library import dancer, library_of, song

from dancenet_core.library.choreography import CALM_LIMIT, Settings, plan, song_grid
from dancenet_core.library.figures import beat_index, entry_steps
from dancenet_core.library.transitions import beat_frames
from dancenet_core.motion import Motion
from dancenet_core.music.features import ONSET_COL
from dancenet_core.skeleton import JOINT_INDEX


def flailing(seconds: float, bpm: float) -> Motion:
    """A dancer whose right forearm whips back and forth four times a second."""
    m = dancer(seconds, bpm, phase=0.5)
    t = np.arange(m.num_frames) / m.fps
    m.rotations[:, JOINT_INDEX["right_elbow"], 1] = 1.2 * np.sin(2 * np.pi * 4.0 * t)
    return m


def _cut_entries(settings: Settings) -> tuple[np.ndarray, int]:
    """Over seeds: each cut's largest entry step as the warp plays it, and how many cuts enter the flailing clip."""
    library = library_of(*[(f"calm{k}", dancer(40, bpm, amplitude=0.3 + 0.1 * k, phase=k))
                           for k, bpm in enumerate((100, 110, 120, 104))], ("flail", flailing(12.3, 110)))  # no loop
    music = song(90, 110)
    grid = song_grid(music, 0.0, 90.0)
    flail = library.names.index("flail")
    played, into_flail = [], 0
    for seed in range(6):
        bars = plan(library, grid, music.features[:, ONSET_COL], np.random.default_rng(seed), settings=settings)
        for (prev, r_prev), (start, r), (_, n_prev), (a, _) in zip(bars[:-1], bars[1:], grid.bars[:-1],
                                                                       grid.bars[1:], strict=True):
            if abs(prev + r_prev * n_prev - start) > 1e-5:  # a cut (a start may lie between two beats)
                clip_s = np.diff(beat_frames(library, np.array([start, start + r]))) / library.fps
                speed = float(clip_s[0]) / (grid.beats[a + 1] - grid.beats[a])
                played.append(float(entry_steps(library, np.array([start]))[0]) * speed)
                into_flail += int(library.beat_clip[beat_index(start)] == flail)
    return np.array(played), into_flail


def test_cuts_never_enter_a_flailing_figure() -> None:
    loose, flailed = _cut_entries(Settings(noise=2.0, calm=0.0))
    assert flailed and (loose > CALM_LIMIT).any()  # without the cost, the plan does cut into the flailing
    calm, flailed = _cut_entries(Settings(noise=2.0))
    # The made-up dancers swing some joint to its 99th percentile within every half second, so no cut here is
    # under CALM_LIMIT; what the cost can do is cut where it is least, never into the flailing.
    assert len(calm) >= 10 and flailed == 0
    assert calm.max() < loose.max() and np.median(calm) <= np.median(loose)
