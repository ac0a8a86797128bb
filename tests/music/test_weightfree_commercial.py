"""The weight-free music analysis (the commercial mode's): beats, tempo, meter and downbeats of made-up songs with
known beats, the layout the engines read, its cache, and that it loads nothing of madmom's."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dancenet_core.music.audio import Audio
from dancenet_core.music.features import FEATURE_SPEC, N_FEATURES, MusicAnalysis
from dancenet_core.music.weightfree import WEIGHTFREE_SPEC, analyze_audio_weightfree, analyze_music_weightfree

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

from synth_songs import SongSpec, synth_song, write_song  # noqa: E402


def f_measure(found: np.ndarray, truth: np.ndarray, window: float = 0.07) -> float:
    """One-to-one matches within `window` (greedy on sorted times: the beats are far apart)."""
    used, hits = set(), 0
    for t in truth:
        i = int(np.argmin(np.abs(found - t))) if len(found) else -1
        if i >= 0 and i not in used and abs(found[i] - t) <= window:
            used.add(i)
            hits += 1
    return 2 * hits / max(len(found) + len(truth), 1)


@pytest.mark.parametrize("spec", [SongSpec(84, 3, False, 24.0, seed=1), SongSpec(150, 4, True, 24.0, seed=2),
                                  SongSpec(64, 4, False, 24.0, seed=3, drums=False),
                                  SongSpec(190, 3, False, 24.0, seed=4, drums=False)], ids=lambda s: s.name)
def test_beats_tempo_and_downbeats_of_made_up_songs(spec: SongSpec) -> None:
    x, beats, downbeats = synth_song(spec)
    a = analyze_audio_weightfree(Audio(x.astype(np.float32), 44100, 44100, 1, Path(spec.name)))
    a.check()  # every field fits the others, as the default analysis' do
    assert a.features.shape == (round(spec.seconds * 10), N_FEATURES)
    assert a.tempo_bpm == pytest.approx(spec.bpm, rel=0.04)  # the octave right
    assert f_measure(a.beat_times, beats) > 0.9
    assert f_measure(a.downbeat_times, downbeats) > 0.8  # 3 or 4 beats to the bar, and where the bar starts
    assert a.features.min() >= 0.0 and a.features.max() <= 1.0


def test_same_columns_another_spec() -> None:
    assert WEIGHTFREE_SPEC.columns == FEATURE_SPEC.columns and WEIGHTFREE_SPEC.fps == FEATURE_SPEC.fps
    assert WEIGHTFREE_SPEC != FEATURE_SPEC  # weights trained on one are not taken for the other's


def test_cached_by_content_apart_from_the_default(tmp_path: Path) -> None:
    song = tmp_path / "song.ogg"
    write_song(SongSpec(120, 4, False, 12.0), song)
    first = analyze_music_weightfree(song, cache_dir=tmp_path / "cache")
    entries = list((tmp_path / "cache").iterdir())
    assert len(entries) == 1
    again = analyze_music_weightfree(song, cache_dir=tmp_path / "cache")
    np.testing.assert_array_equal(first.beat_times, again.beat_times)
    with pytest.raises(ValueError, match="version"):
        MusicAnalysis.load(entries[0])  # the default analysis never reads it as its own


def test_loads_nothing_of_madmom(tmp_path: Path) -> None:
    song = tmp_path / "song.ogg"
    write_song(SongSpec(100, 4, False, 8.0), song)
    code = ("import sys; from dancenet_core.music.weightfree import analyze_music_weightfree as a; "
            f"a({str(song)!r}, use_cache=False); print(sorted(m for m in sys.modules if m.startswith('madmom')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.strip() == "[]"
