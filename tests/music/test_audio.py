"""Audio loading: every supported format and rate decodes to the same mono 44.1 kHz signal; bad input
gives one clear line."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from made_up import encoded_click_track
from scipy.signal import chirp, resample_poly

from dancenet_core.errors import DanceNetError
from dancenet_core.music import audio
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, MIN_DURATION_S, load_audio, resample
from dancenet_core.music.features import analyze_music

DUR = 4.0


def wave(sr: int, dur: float = DUR) -> np.ndarray:
    """A non-periodic test signal (log chirp 150 Hz-3 kHz, slow tremolo), defined at any sample rate."""
    t = np.arange(int(round(sr * dur))) / sr
    return (0.4 * chirp(t, 150, dur, 3000, method="logarithmic") * (0.6 + 0.4 * np.sin(2 * np.pi * 1.3 * t))).astype(
        np.float32
    )


def write(path: Path, sr: int, channels: int, fmt: str, subtype: str) -> np.ndarray:
    """Write channel c as (1 - 0.2 c) x wave; return the expected mono mix at 44.1 kHz."""
    x = np.stack([wave(sr) * (1 - 0.2 * c) for c in range(channels)], axis=1)
    sf.write(str(path), x, sr, format=fmt, subtype=subtype)
    return wave(MADMOM_SAMPLE_RATE) * (1 - 0.1 * (channels - 1))


def rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    """Relative RMS error away from the edges (codecs and resamplers ring there)."""
    n = min(len(a), len(b))
    mid = slice(4410, n - 4410)
    return float(np.sqrt(np.mean((a[mid] - b[mid]) ** 2) / np.mean(b[mid] ** 2)))


FORMATS = [
    ("wav", "WAV", "PCM_16", 22050, 2, 0.005),
    ("wav", "WAV", "FLOAT", 8000, 1, 0.005),
    ("wav", "WAV", "PCM_24", 44100, 1, 0.005),
    ("flac", "FLAC", "PCM_24", 48000, 1, 0.005),
    ("flac", "FLAC", "PCM_16", 96000, 2, 0.005),
    ("ogg", "OGG", "VORBIS", 32000, 2, 0.05),
    ("mp3", "MP3", "MPEG_LAYER_III", 44100, 2, 0.05),
    ("mp3", "MP3", "MPEG_LAYER_III", 22050, 1, 0.05),
    ("opus", "OGG", "OPUS", 48000, 1, 0.05),
    ("opus", "OGG", "OPUS", 16000, 2, 0.05),
]


@pytest.mark.parametrize(("ext", "fmt", "subtype", "sr", "channels", "tol"), FORMATS)
def test_formats_decode_to_same_signal(
    tmp_path: Path, ext: str, fmt: str, subtype: str, sr: int, channels: int, tol: float
) -> None:
    path = tmp_path / f"song_{sr}_{channels}.{ext}"
    expected = write(path, sr, channels, fmt, subtype)
    a = load_audio(path)
    assert a.samples.dtype == np.float32
    assert a.samples.ndim == 1
    assert a.sample_rate == MADMOM_SAMPLE_RATE
    assert (a.source_sample_rate, a.source_channels) == (sr, channels)
    assert abs(len(a.samples) - len(expected)) <= 1
    assert a.duration_s == pytest.approx(DUR, abs=1e-3)
    assert rel_rms(a.samples, expected) < tol


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="ffmpeg not installed")
@pytest.mark.parametrize("ext", ["mp3", "opus"])
def test_ffmpeg_encoded_files_align(tmp_path: Path, ext: str) -> None:
    """Files from a common encoder (with its own delay and padding) come back aligned, not shifted."""
    src = tmp_path / "src.wav"
    expected = write(src, 48000, 2, "WAV", "PCM_16")
    dst = tmp_path / f"song.{ext}"
    subprocess.run(["ffmpeg", "-loglevel", "error", "-y", "-i", str(src), str(dst)], check=True)
    got = load_audio(dst).samples
    assert abs(len(got) - len(expected)) <= 1
    assert rel_rms(got, expected) < 0.1


def test_block_decoding_and_resampling_match_one_shot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Tiny blocks force every seam path that a 30-minute song takes."""
    monkeypatch.setattr(audio, "_DECODE_BLOCK", 1000)
    monkeypatch.setattr(audio, "_RESAMPLE_BLOCK", 5000)
    path = tmp_path / "song.flac"
    write(path, 48000, 2, "FLAC", "PCM_24")
    x, _ = sf.read(str(path), dtype="float32")
    one_shot = resample_poly(x.mean(axis=1), 147, 160).astype(np.float32)
    np.testing.assert_allclose(load_audio(path).samples, one_shot, atol=1e-6)


@pytest.mark.parametrize(("src", "dst"), [(48000, 44100), (22050, 44100), (8000, 44100), (96000, 44100)])
def test_resample_matches_scipy(src: int, dst: int) -> None:
    x = np.random.default_rng(0).standard_normal(200_003).astype(np.float32)
    np.testing.assert_allclose(resample(x, src, dst), resample_poly(x, dst, src), atol=1e-5)


def test_madmom_signal_is_a_view(tmp_path: Path) -> None:
    path = tmp_path / "song.wav"
    write(path, 44100, 1, "WAV", "FLOAT")
    a = load_audio(path)
    sig = a.madmom_signal()
    assert sig.sample_rate == MADMOM_SAMPLE_RATE
    assert sig.num_channels == 1
    assert np.shares_memory(sig, a.samples)


def _check_error(path: Path, *words: str) -> None:
    with pytest.raises(DanceNetError) as err:
        load_audio(path)
    msg = str(err.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


@pytest.mark.skipif(sys.platform in ("win32", "darwin"), reason="a name that is not UTF-8 needs a file system "
                    "that stores bytes")
def test_a_song_whose_name_is_not_utf8_is_read(tmp_path: Path) -> None:
    """`caf\\xe9.wav` from an old Latin-1 archive: decoded like any other song (soundfile is given the name's
    bytes, not a str it would encode strictly)."""
    wav, _ = encoded_click_track(tmp_path, ())
    latin1 = tmp_path / os.fsdecode(b"caf\xe9.wav")
    wav.rename(latin1)
    plain = tmp_path / "cafe.wav"
    shutil.copyfile(latin1, plain)
    np.testing.assert_array_equal(load_audio(latin1).samples, load_audio(plain).samples)


def test_missing_file(tmp_path: Path) -> None:
    _check_error(tmp_path / "nope.wav", "not found", "nope.wav")


def test_empty_file(tmp_path: Path) -> None:
    (tmp_path / "empty.mp3").write_bytes(b"")
    _check_error(tmp_path / "empty.mp3", "empty")


def test_garbage_named_mp3(tmp_path: Path) -> None:
    path = tmp_path / "garbage.mp3"
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 50_000, dtype=np.uint8).tobytes())
    _check_error(path, "cannot decode", "ffmpeg")


def test_text_file(tmp_path: Path) -> None:
    path = tmp_path / "notes.wav"
    path.write_text("not audio at all\n" * 100)
    _check_error(path, "cannot decode")


def test_folder(tmp_path: Path) -> None:
    _check_error(tmp_path, "folder")


def test_silent(tmp_path: Path) -> None:
    path = tmp_path / "silence.wav"
    sf.write(str(path), np.zeros(44100 * 5, np.float32), 44100)
    _check_error(path, "silent")


def test_too_short(tmp_path: Path) -> None:
    path = tmp_path / "blip.ogg"
    sf.write(str(path), wave(44100, dur=MIN_DURATION_S / 2), 44100, format="OGG", subtype="VORBIS")
    _check_error(path, "too short", f"{MIN_DURATION_S:g} seconds")


def test_header_without_samples(tmp_path: Path) -> None:
    path = tmp_path / "header_only.wav"
    sf.write(str(path), np.zeros((0, 1), np.float32), 44100)
    _check_error(path, "no samples")


@pytest.mark.parametrize("ext", ["m4a", "mp4"])
def test_m4a_and_mp4_analyse_to_the_wav_beats(tmp_path: Path, ext: str) -> None:
    """AAC (an m4a, the audio track of an mp4), which libsndfile cannot read, is decoded by imageio-ffmpeg's
    ffmpeg into the signal the WAV gives: same length, aligned (no encoder delay left), the same beats."""
    wav, (song,) = encoded_click_track(tmp_path, (ext,))
    got, expected = load_audio(song), load_audio(wav)
    assert (got.source_sample_rate, got.source_channels) == (44100, 2)
    assert abs(len(got.samples) - len(expected.samples)) <= 1
    assert rel_rms(got.samples, expected.samples) < 0.5  # AAC blurs the clicks' noise; 1024 samples late: 1.4
    beats, truth = (analyze_music(p, use_cache=False, workers=1).beat_times for p in (song, wav))
    assert len(beats) == len(truth)
    np.testing.assert_allclose(beats, truth, atol=0.02)


@pytest.mark.parametrize("cut", ["truncated", "garbled"])
def test_a_broken_m4a_is_one_line(tmp_path: Path, cut: str) -> None:
    _, (song,) = encoded_click_track(tmp_path, ("m4a",))
    data = song.read_bytes()
    song.write_bytes(data[: len(data) // 3] if cut == "truncated" else data[:64] + bytes(len(data) - 64))
    _check_error(song, "cannot decode clicks.m4a", "ffmpeg")


def test_without_ffmpeg_nor_blender_an_m4a_says_what_to_install(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    _, (song,) = encoded_click_track(tmp_path, ("m4a",))
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails as if it were not installed
    monkeypatch.setitem(sys.modules, "aud", None)
    _check_error(song, "cannot decode clicks.m4a", "pip install imageio-ffmpeg")
