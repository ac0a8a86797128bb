"""Audio loading: any common format and sample rate to mono float32 at the rate madmom's networks expect.

Decoding is done block by block with soundfile (libsndfile reads wav, flac, ogg/vorbis, opus and mp3), the
mix-down and the polyphase resampling too, so a long song never holds more than its mono signal plus one
block in memory.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import gcd
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import soundfile as sf
from scipy.signal import resample_poly

from ..errors import DanceNetError

if TYPE_CHECKING:
    from madmom.audio.signal import Signal

# madmom's onset, downbeat and chroma networks were trained on 44.1 kHz audio.
MADMOM_SAMPLE_RATE = 44100
# Shorter songs cannot hold even one bar of a slow waltz plus the beat tracker's warm-up.
MIN_DURATION_S = 3.0
# Peak level under which a file counts as silent (-80 dBFS).
SILENCE_PEAK = 1e-4
# Sample rates a real recording has; a damaged header can claim any, and resampling from one far outside
# this range would take hours.
MIN_SAMPLE_RATE, MAX_SAMPLE_RATE = 4000, 384000
SUPPORTED_FORMATS = ("wav", "flac", "ogg", "mp3", "opus")

_DECODE_BLOCK = 1 << 20  # frames decoded per soundfile read
_DECODE_PREALLOCATE = 1 << 25  # at most this many frames are allocated up front (the buffer grows past it)
_RESAMPLE_BLOCK = 1 << 21  # input samples resampled per call (plus context)
_RESAMPLE_CONTEXT = 4096  # input samples each side; the default FIR reaches ~10 samples


@dataclass
class Audio:
    """A mono signal with where it came from; `samples` is float32 in [-1, 1] at `sample_rate`."""

    samples: np.ndarray
    sample_rate: int
    source_sample_rate: int
    source_channels: int
    path: Path

    @property
    def duration_s(self) -> float:
        return len(self.samples) / self.sample_rate

    def madmom_signal(self) -> Signal:
        """The samples as a madmom `Signal` (no copy), what its processors take instead of a file name."""
        # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
        from madmom.audio.signal import Signal

        if self.sample_rate != MADMOM_SAMPLE_RATE:
            raise ValueError(f"madmom needs {MADMOM_SAMPLE_RATE} Hz audio, this is {self.sample_rate} Hz")
        return Signal(self.samples, sample_rate=self.sample_rate, num_channels=1)


def load_audio(path: str | Path, sample_rate: int = MADMOM_SAMPLE_RATE) -> Audio:
    """Decode `path`, mix it down to mono and resample it; raise DanceNetError for anything unusable."""
    path = Path(path)
    if not path.exists():
        raise DanceNetError(f"audio file not found: {path} (check the path)")
    if not path.is_file():
        raise DanceNetError(f"not an audio file but a folder or device: {path}")
    if path.stat().st_size == 0:
        raise DanceNetError(f"audio file is empty (0 bytes): {path}; export or download it again")
    try:
        with sf.SoundFile(str(path)) as f:
            source_rate, channels = int(f.samplerate), int(f.channels)
            if not MIN_SAMPLE_RATE <= source_rate <= MAX_SAMPLE_RATE:
                raise DanceNetError(
                    f"{path.name} says its sample rate is {source_rate} Hz, which no song has (the file is "
                    f"damaged?); export it again or convert it with e.g. `ffmpeg -i {path.name} song.wav`"
                )
            mono = _decode_mono(f)
    except (sf.LibsndfileError, RuntimeError, TypeError) as e:
        raise DanceNetError(
            f"cannot decode {path.name} as audio ({_one_line(e)}); supported formats: "
            f"{', '.join(SUPPORTED_FORMATS)}; convert it with e.g. `ffmpeg -i {path.name} song.wav`"
        ) from e
    if len(mono) == 0:
        raise DanceNetError(f"audio file has no samples: {path}; export or download it again")
    bad = int(np.count_nonzero(~np.isfinite(mono)))
    if bad:
        raise DanceNetError(
            f"{path.name} holds {bad} samples that are not numbers (NaN or infinity): the file is damaged; "
            f"export it again or convert it with e.g. `ffmpeg -i {path.name} song.wav`"
        )
    samples = resample(mono, source_rate, sample_rate)
    audio = Audio(samples, sample_rate, source_rate, channels, path)
    if audio.duration_s < MIN_DURATION_S:
        raise DanceNetError(
            f"audio is too short ({audio.duration_s:.2f} s) in {path.name}; "
            f"give a song of at least {MIN_DURATION_S:g} seconds"
        )
    if float(np.max(np.abs(samples))) < SILENCE_PEAK:
        raise DanceNetError(f"audio is silent (peak below -80 dBFS) in {path.name}; check the file plays")
    return audio


def resample(samples: np.ndarray, source_rate: int, target_rate: int) -> np.ndarray:
    """Polyphase resampling in blocks; each block is cut at a multiple of the reduced down-factor so that
    its output lands on the global output grid, with enough context that the seams match a one-shot call."""
    samples = np.asarray(samples, dtype=np.float32)
    if source_rate == target_rate:
        return samples
    g = gcd(int(source_rate), int(target_rate))
    up, down = int(target_rate) // g, int(source_rate) // g
    n_out = -(-len(samples) * up // down)
    out = np.empty(n_out, dtype=np.float32)
    step = max(down, _RESAMPLE_BLOCK // down * down)
    ctx = -(-_RESAMPLE_CONTEXT // down) * down
    for start in range(0, len(samples), step):
        lo, hi = max(0, start - ctx), min(len(samples), start + step + ctx)
        y = resample_poly(samples[lo:hi], up, down)
        o0, o1 = start * up // down, min(n_out, -(-min(len(samples), start + step) * up // down))
        off = o0 - lo * up // down
        out[o0:o1] = y[off : off + o1 - o0]
    return out


def _decode_mono(f: sf.SoundFile) -> np.ndarray:
    """Read every frame as float32 and average the channels, one block at a time."""
    expected = min(max(int(f.frames), 0), _DECODE_PREALLOCATE)  # a damaged header can claim any count
    out = np.empty(expected, dtype=np.float32)
    n = 0
    while True:  # not f.blocks(): it pads up to the header's frame count, which a damaged file sets to billions
        block = f.read(_DECODE_BLOCK, dtype="float32", always_2d=True)
        if not len(block):
            break
        mono = block.mean(axis=1, dtype=np.float32) if block.shape[1] > 1 else block[:, 0]
        if n + len(mono) > len(out):  # frame counts of compressed formats can be estimates
            out = np.concatenate([out[:n], np.empty(max(len(mono), len(out) // 4), np.float32)])
        out[n : n + len(mono)] = mono
        n += len(mono)
    return out[:n]


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split()) or type(e).__name__
