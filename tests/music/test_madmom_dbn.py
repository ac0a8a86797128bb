"""The compiled Viterbi decode against madmom's own: the same path and log probability, bit for bit, for
both bar lengths of the analysis' downbeat DBN, on click tracks and real music; and the same beats."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from made_up import click_track

from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, load_audio
from dancenet_core.music.features import ACT_FPS, BEATS_PER_BAR, _tracker
from dancenet_core.music.madmom_dbn import CompiledHMM, _viterbi, load_compiled
from dancenet_core.music.madmom_nets import OnsetAndBeat

REPO = Path(__file__).resolve().parents[2]


def madmom_tracker():
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor

    return DBNDownBeatTrackingProcessor(beats_per_bar=list(BEATS_PER_BAR), fps=ACT_FPS)


def activations(x: np.ndarray) -> np.ndarray:
    from madmom.audio.signal import Signal

    return OnsetAndBeat()(Signal(x, sample_rate=MADMOM_SAMPLE_RATE, num_channels=1))[1]


def assert_same_decode(act: np.ndarray) -> None:
    ours = _tracker()
    for hmm, compiled in zip(madmom_tracker().hmms, ours.hmms, strict=True):
        assert isinstance(compiled, CompiledHMM)
        path, log_prob = hmm.viterbi(act)
        our_path, our_log_prob = compiled.viterbi(act)
        assert our_log_prob == log_prob
        assert our_path.dtype == path.dtype
        np.testing.assert_array_equal(our_path, path)
    np.testing.assert_array_equal(ours(act), madmom_tracker()(act))


@pytest.mark.parametrize("bpm", [60, 120, 180])
def test_click_tracks(bpm: int) -> None:
    assert_same_decode(activations(click_track(bpm)[0]))


def test_example_song() -> None:
    """The bundled 53-s waltz, whole."""
    assert_same_decode(activations(load_audio(REPO / "examples" / "example_song.ogg").samples))


def test_real_song(shared_data: Path) -> None:
    """One 60-s DBN window of a real waltz recording (what the analysis decodes at a time)."""
    x = load_audio(shared_data / "dance_with_melody" / "DANCE_W_1.ogg").samples
    assert_same_decode(activations(x[30 * MADMOM_SAMPLE_RATE : 90 * MADMOM_SAMPLE_RATE]))


@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning")  # madmom's log densities of the zeros
def test_coarse_activations_and_impossible_states() -> None:
    """Activations of a few values (so that many paths score alike, and madmom's order of comparison
    decides), with exact zeros (log densities of -inf: states no path may pass through)."""
    rng = np.random.default_rng(0)
    act = rng.choice(np.array([0.0, 0.125, 0.25], np.float32), size=(1500, 2))
    act[::50, 0] = 0.5
    act[::200, 1] = 0.5
    for hmm in madmom_tracker().hmms:
        path, log_prob = hmm.viterbi(act)
        our_path, our_log_prob = CompiledHMM(hmm).viterbi(act)
        assert np.isfinite(log_prob)
        assert our_log_prob == log_prob
        np.testing.assert_array_equal(our_path, path)


def test_no_valid_path_warns_like_madmom() -> None:
    hmm = madmom_tracker().hmms[0]
    act = np.full((100, 2), 0.5, np.float32)  # beat + downbeat = 1: every no-beat state is impossible
    with pytest.warns(RuntimeWarning):
        path, log_prob = hmm.viterbi(act)
    with pytest.warns(RuntimeWarning, match="-inf log probability"):
        our_path, our_log_prob = CompiledHMM(hmm).viterbi(act)
    assert our_log_prob == log_prob == -np.inf
    assert len(our_path) == len(path) == 0


def test_load_compiled_matches_the_analysis_call() -> None:
    """load_compiled (run before the workers fork) compiles the one signature the analysis then calls."""
    load_compiled()
    _tracker()(activations(click_track(120, dur=6.0)[0]))
    assert len(_viterbi.signatures) == 1
