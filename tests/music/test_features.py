"""Music features: beats on click tracks, the [T, 15] shape rule, block seams, the cache, bad input."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from made_up import REPO, click_track, music

from dancenet_core.errors import DanceNetError
from dancenet_core.music import features as F
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, Audio
from dancenet_core.music.features import MusicAnalysis, analyze_audio, analyze_music

SR = MADMOM_SAMPLE_RATE


def f_measure(detections: np.ndarray, annotations: np.ndarray, window: float = 0.07) -> float:
    """MIREX beat F-measure: each annotation matches at most one detection within +-window."""
    left = list(detections)
    hits = 0
    for a in annotations:
        if left:
            j = int(np.argmin(np.abs(np.asarray(left) - a)))
            if abs(left[j] - a) <= window:
                hits += 1
                left.pop(j)
    precision = hits / max(1, len(detections))
    recall = hits / max(1, len(annotations))
    return 2 * precision * recall / max(precision + recall, 1e-12)


def as_audio(x: np.ndarray, name: str = "test.wav") -> Audio:
    return Audio(x.astype(np.float32), SR, SR, 1, Path(name))


@pytest.mark.parametrize("bpm", [60, 90, 120, 150, 180])
def test_click_track_beats(bpm: int) -> None:
    x, truth = click_track(bpm)
    a = analyze_audio(as_audio(x), workers=1)
    assert f_measure(a.beat_times, truth) >= 0.95
    assert a.tempo_bpm == pytest.approx(bpm, rel=0.03)
    assert f_measure(a.downbeat_times, truth[::4]) >= 0.8


@pytest.mark.parametrize("dur", [5.0, 7.04, 7.06])
def test_feature_shape_rule(dur: float) -> None:
    """T = floor(10 * duration + 0.5): 7.04 s -> 70 frames, 7.06 s -> 71."""
    a = analyze_audio(as_audio(music(dur)), workers=1)
    t = int(np.floor(10 * dur + 0.5))
    assert a.features.shape == (t, 15)
    assert a.features.dtype == np.float32
    assert a.mel is not None
    assert a.mel.shape == (t, F.MEL_BANDS)
    assert a.fps == 10
    assert a.duration_s == pytest.approx(dur, abs=1e-4)
    assert np.all(np.isfinite(a.features))
    assert np.all(a.features >= 0)
    assert a.features[:, F.CHROMA_COLS].max() > 0.1
    assert a.features[:, F.ONSET_COL].max() > 0.1


def test_blocks_stitch_like_one_shot(monkeypatch: pytest.MonkeyPatch) -> None:
    """With 3-s blocks a 9.53-s song takes four blocks in two worker processes; chroma and mel (whose
    context fits in the margins) must equal a one-shot madmom run, frame for frame."""
    x = music(9.53, seed=3)
    sig = as_audio(x).madmom_signal()
    _, chroma_p, mel_p = F._processors()
    chroma, mel = chroma_p(sig), mel_p(sig)
    monkeypatch.setattr(F, "BLOCK_S", 3)
    monkeypatch.setattr(F, "CONTEXT_S", 1)
    a = analyze_audio(as_audio(x), workers=2)
    t = a.num_frames
    assert t == 95
    np.testing.assert_allclose(a.features[:, F.CHROMA_COLS], chroma[:t], atol=1e-6)
    np.testing.assert_allclose(a.mel, mel[:t], atol=1e-5)


_SAME_EITHER_WAY = """
from pathlib import Path
import numpy as np
from made_up import music
from dancenet_core.music import features as F
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, Audio
x = music(9.53, seed=4).astype(np.float32)
F.BLOCK_S, F.CONTEXT_S = 3, 1
audio = lambda: Audio(x, MADMOM_SAMPLE_RATE, MADMOM_SAMPLE_RATE, 1, Path("test.wav"))
forked, inline = F.analyze_audio(audio(), workers=2), F.analyze_audio(audio(), workers=1)
print(np.array_equal(forked.features, inline.features), np.array_equal(forked.beat_times, inline.beat_times))
"""


def test_worker_processes_give_the_in_process_answer() -> None:
    """The command line analyses in worker processes, Blender in its own process: the features must be the
    same to the bit, or one seed would dance differently in the two (sampling magnifies any difference). In a
    process with two BLAS threads, since how a matrix product is split between threads changes its rounding."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"} | {
        "OPENBLAS_NUM_THREADS": "2", "PYTHONPATH": os.pathsep.join([str(REPO), str(REPO / "tests")])}
    out = subprocess.run([sys.executable, "-c", _SAME_EITHER_WAY], capture_output=True, text=True, env=env,
                         cwd=REPO, timeout=300, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["True", "True"]


class _FakeNet:
    """Counts frames the way madmom frames a signal, without the cost of its networks."""

    def __init__(self, fps: int, width: int | None) -> None:
        self.fps, self.width = fps, width

    def __call__(self, sig: np.ndarray) -> np.ndarray:
        from madmom.audio.signal import FramedSignal

        n = len(FramedSignal(sig, frame_size=2048, fps=self.fps))
        return np.zeros(n if self.width is None else (n, self.width), np.float32)


def test_ten_minute_song_shape(monkeypatch: pytest.MonkeyPatch) -> None:
    """The block and DBN-window arithmetic over a 10-minute song (networks replaced by frame counters)."""
    onset, beat = _FakeNet(100, None), _FakeNet(100, 2)
    fakes = (lambda sig: (onset(sig), beat(sig)), _FakeNet(10, 12), _FakeNet(10, F.MEL_BANDS))
    monkeypatch.setattr(F, "_processors", lambda: fakes)
    dur = 600.037
    x = np.full(int(round(dur * SR)), 0.1, np.float32)
    a = analyze_audio(as_audio(x), workers=1)
    assert a.features.shape == (6000, 15)
    assert a.mel is not None
    assert a.mel.shape == (6000, F.MEL_BANDS)
    assert a.tempo_bpm == 0.0
    assert len(a.beat_times) == 0


def test_merge_beats_drops_seam_duplicates() -> None:
    w1 = np.array([[0.5, 1], [1.0, 2], [1.5, 3], [2.0, 1]])
    w2 = np.array([[2.01, 1], [2.5, 2], [3.0, 3]])
    beats, downbeats = F._merge_beats([w1, w2])
    np.testing.assert_allclose(beats, [0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    np.testing.assert_allclose(downbeats, [0.5, 2.0])


@pytest.fixture
def song(tmp_path: Path) -> Path:
    path = tmp_path / "song.wav"
    sf.write(str(path), music(6.0, seed=1), SR)
    return path


def test_cache_is_identical_and_not_computed_again(song: Path, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """A cached song is read, never analysed again (how fast that is: bench/, not a timed test)."""
    cache = tmp_path / "cache"
    seen: list[float] = []
    cold = analyze_music(song, cache_dir=cache, with_mel=True, workers=1, progress=seen.append)

    def analysed_again(*_a: object, **_k: object) -> None:
        raise AssertionError("a cached song was analysed again")

    monkeypatch.setattr(F, "analyze_audio", analysed_again)
    monkeypatch.setattr(F, "load_audio", analysed_again)
    warm = analyze_music(song, cache_dir=cache, with_mel=True)
    assert len(list(cache.glob("*.npz"))) == 1
    for name in ("features", "beat_times", "downbeat_times", "mel"):
        np.testing.assert_array_equal(getattr(cold, name), getattr(warm, name))
    assert (cold.tempo_bpm, cold.duration_s) == (warm.tempo_bpm, warm.duration_s)
    assert seen == sorted(seen)
    assert seen[-1] == 1.0
    assert analyze_music(song, cache_dir=cache).mel is None  # mel only on request


def test_cache_key_follows_content(song: Path, tmp_path: Path) -> None:
    copy = tmp_path / "renamed.wav"
    copy.write_bytes(song.read_bytes())
    assert F.cache_key(song) == F.cache_key(copy)
    sf.write(str(copy), music(6.0, seed=2), SR)
    assert F.cache_key(song) != F.cache_key(copy)


def test_cache_key_includes_settings(song: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    before = F.cache_key(song)
    monkeypatch.setattr(F, "FEATURE_VERSION", "other")
    assert F.cache_key(song) != before


def test_cache_dir_from_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DANCENET_CACHE", raising=False)
    assert F.default_cache_dir() == Path.home() / ".cache" / "dancenet" / "features"
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "env_cache"))
    assert F.default_cache_dir() == tmp_path / "env_cache" / "features"


def test_save_load_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    a = MusicAnalysis(rng.random((50, 15), dtype=np.float32), np.array([0.5, 1.0]), np.array([0.5]), 120.0, 5.0)
    a.save(tmp_path / "a.npz")
    b = MusicAnalysis.load(tmp_path / "a.npz")
    np.testing.assert_array_equal(a.features, b.features)
    assert b.mel is None
    assert (b.tempo_bpm, b.duration_s, b.fps) == (120.0, 5.0, 10)


@pytest.mark.parametrize(
    ("name", "content", "words"),
    [
        ("missing.wav", None, "not found"),
        ("empty.wav", b"", "empty"),
        ("garbage.mp3", bytes(range(256)) * 200, "cannot decode"),
    ],
)
def test_bad_files(tmp_path: Path, name: str, content: bytes | None, words: str) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(DanceNetError, match=words):
        analyze_music(path, cache_dir=tmp_path / "cache")


def test_silent_and_short(tmp_path: Path) -> None:
    silent, short = tmp_path / "silent.flac", tmp_path / "short.wav"
    sf.write(str(silent), np.zeros(SR * 5, np.float32), SR)
    sf.write(str(short), music(1.0), SR)
    with pytest.raises(DanceNetError, match="silent"):
        analyze_music(silent, cache_dir=tmp_path / "cache")
    with pytest.raises(DanceNetError, match="too short"):
        analyze_music(short, cache_dir=tmp_path / "cache")
    assert not list((tmp_path / "cache").glob("*.npz"))




def _entry_with(entry: Path, good: Path, field: str, value: object) -> None:
    """`good`'s cache entry with one field (an array, or a key of its metadata) replaced."""
    import json

    with np.load(good) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    if field in meta:
        meta[field] = value
        arrays["meta"] = np.array(json.dumps(meta))
    elif field == "meta":
        arrays["meta"] = np.array(value)
    else:
        arrays[field] = value(arrays[field]) if callable(value) else value
    np.savez(entry, **arrays)


BAD_FIELDS = {
    "negative duration": ("duration_s", -5.0),
    "huge duration": ("duration_s", 1e12),
    "duration not the frames'": ("duration_s", 3.0),
    "other fps": ("fps", 1000),
    "infinite fps": ("fps", float("inf")),
    "negative tempo": ("tempo_bpm", -1.0),
    "tempo not the beats'": ("tempo_bpm", 999.0),
    "meta nested deep": ("meta", "[" * 100_000 + "]" * 100_000),
    "meta not a mapping": ("meta", "[1, 2]"),
    "beats unsorted": ("beat_times", lambda b: b[::-1].copy()),
    "beats after the song": ("beat_times", lambda b: b + 100.0),
    "beats as a table": ("beat_times", lambda b: b[:, None]),
    "downbeats not beats": ("downbeat_times", lambda d: d + 0.01),
    "features as text": ("features", lambda f: f.astype(str)),
    "features as whole numbers": ("features", lambda f: f.astype(np.int64)),
    "a frame missing": ("features", lambda f: f[:-2]),
    "mel of another width": ("mel", lambda m: m[:, :10]),
}


@pytest.mark.parametrize("case", list(BAD_FIELDS))
def test_cache_metadata_must_fit_the_arrays(song: Path, tmp_path: Path, case: str) -> None:
    """An entry whose fields disagree with each other (a negative or huge duration, a tempo or
    fps that is not the arrays', any exception while reading it) is not an analysis: a ValueError, which
    `analyze_music` answers by recomputing with its one-line notice."""
    good = tmp_path / "cache"
    analyze_music(song, cache_dir=good, with_mel=True, workers=1)
    (entry,) = good.glob("*.npz")
    field, value = BAD_FIELDS[case]
    _entry_with(tmp_path / "bad.npz", entry, field, value)
    with pytest.raises(ValueError) as info:
        MusicAnalysis.load(tmp_path / "bad.npz")
    assert "\n" not in str(info.value)


def test_cache_entry_with_a_bad_duration_is_recomputed(song: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    cache = tmp_path / "cache"
    first = analyze_music(song, cache_dir=cache, workers=1)
    (entry,) = cache.glob("*.npz")
    _entry_with(entry, entry, "duration_s", -5.0)
    capsys.readouterr()
    again = analyze_music(song, cache_dir=cache, workers=1)
    notice = capsys.readouterr().err.strip()
    assert notice.startswith("dancenet: the cached analysis") and "\n" not in notice, notice
    assert again.duration_s == first.duration_s
    assert MusicAnalysis.load(entry).duration_s == first.duration_s  # replaced by a good entry
