"""The plan keeps the library's extremes apart: a cut between two stretches that both move one joint far more than
the library's dancers usually do (`Settings.pile`) costs, so the loudest bars do not get the library's most
extreme figures back to back, each cut into the next, where no dancer danced them so."""

from __future__ import annotations

import numpy as np
from test_library import dancer, library_of, song

from dancenet_core.library.choreography import Settings, plan, song_grid
from dancenet_core.library.figures import stretch_kinetics
from dancenet_core.library.store import MotionLibrary
from dancenet_core.motion import Motion
from dancenet_core.music.features import ONSET_COL
from dancenet_core.skeleton import BODY_JOINTS, JOINT_INDEX


def pumping(seconds: float, bpm: float, phase: float) -> Motion:
    """A dancer whose right arm swings from the hip to high overhead with her legs' swing."""
    m = dancer(seconds, bpm, amplitude=0.4, phase=phase)
    t = np.arange(m.num_frames) / m.fps
    m.rotations[:, JOINT_INDEX["right_shoulder"], 2] = 0.4 + 1.4 * np.sin(np.pi * bpm / 60.0 * t + phase)
    return m


def _calm_and_pumping() -> MotionLibrary:
    return library_of(*[(f"calm{k}", dancer(30, bpm, amplitude=0.3 + 0.1 * k, phase=k))
                        for k, bpm in enumerate((100, 110, 120))],
                      *[(f"pump{k}", pumping(12.3, 110, phase=k)) for k in range(3)])  # no loops


def _piled_cuts(settings: Settings) -> tuple[int, int]:
    """Over seeds, on a song that grows louder: how many cuts join two stretches that both lie a standard
    deviation past the library's median in the same feature, and how many cuts there are."""
    library = _calm_and_pumping()
    music = song(80, 110)
    onset = music.features[:, ONSET_COL] * np.linspace(0.2, 1.0, len(music.features))
    grid = song_grid(music, 0.0, 80.0)
    after, before = stretch_kinetics(library, grid.meter)
    piled = cuts = 0
    for seed in range(6):
        bars = plan(library, grid, onset, np.random.default_rng(seed), settings=settings)
        for (prev, r_prev), (start, _r), (_, n_prev) in zip(bars[:-1], bars[1:], grid.bars[:-1], strict=True):
            end = prev + r_prev * n_prev
            if end != start:
                cuts += 1
                piled += int((np.minimum(before[int(round(end))], after[int(round(start))]) > 1.0).any())
    return piled, cuts


def test_a_pumping_arm_stands_out_where_it_pumps() -> None:
    library = _calm_and_pumping()
    after, before = stretch_kinetics(library, 4)
    wrist_up_down = BODY_JOINTS + JOINT_INDEX["right_wrist"]
    pump = np.isin(library.beat_clip, [library.names.index(f"pump{k}") for k in range(3)])
    for x in (after, before):
        assert x.min() >= 0.0
        assert x[~pump, wrist_up_down].max() == 0.0
        assert np.median(x[pump, wrist_up_down]) > 0.5


def test_the_loudest_bars_do_not_pile_extremes_cut_on_cut() -> None:
    loose, loose_cuts = _piled_cuts(Settings(calm=0.0, pile=0.0))
    kept, kept_cuts = _piled_cuts(Settings(calm=0.0))
    assert loose >= 30 and loose_cuts >= 100 and kept_cuts >= 100  # without the cost the plan does pile them
    assert kept <= loose // 10
