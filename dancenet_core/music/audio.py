"""Audio loading: any common format and sample rate to mono float32 at the rate madmom's networks expect.

Decoding is done block by block with soundfile (libsndfile reads wav, flac, ogg/vorbis, opus and mp3), the
mix-down and the polyphase resampling too, so a long song never holds more than its mono signal plus one
block in memory. What libsndfile cannot read (m4a/AAC, the audio of a video, wma...) is decoded by the ffmpeg
that the imageio-ffmpeg wheel bundles, through a pipe and block by block too, or, inside Blender, where the
extension leaves that wheel out, by Blender's own audio module (`aud`, built on Blender's ffmpeg).
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from math import gcd
from pathlib import Path
from types import ModuleType
from typing import IO, TYPE_CHECKING

import numpy as np

from ..errors import DanceNetError

if TYPE_CHECKING:
    import soundfile as sf
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
FFMPEG_FORMATS = ("m4a", "aac", "mp4", "webm", "wma")  # and the rest of ffmpeg's: with imageio-ffmpeg, or in Blender

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
    import soundfile as sf  # here, not at the top: training on a GPU machine imports this module without it

    try:
        # bytes on POSIX: a name that is not UTF-8 (kept by Python as lone surrogates) is soundfile's str error
        with sf.SoundFile(str(path) if os.name == "nt" else os.fsencode(path)) as f:
            source_rate, channels = int(f.samplerate), int(f.channels)
            _check_rate(path, source_rate)
            mono = _mono(_soundfile_blocks(f), f.frames)
    except (sf.LibsndfileError, RuntimeError, TypeError) as e:
        source_rate, channels, mono = _decode_other(path, e)
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
    from scipy.signal import resample_poly  # 0.3 s to import on Python 3.13: only a song at another rate pays it

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


def _check_rate(path: Path, rate: int) -> None:
    if not MIN_SAMPLE_RATE <= rate <= MAX_SAMPLE_RATE:
        raise DanceNetError(
            f"{path.name} says its sample rate is {rate} Hz, which no song has (the file is "
            f"damaged?); export it again or convert it with e.g. `ffmpeg -i {path.name} song.wav`"
        )


def _soundfile_blocks(f: sf.SoundFile) -> Iterator[np.ndarray]:
    """[frames, channels] float32 blocks until the end; not f.blocks(): it pads up to the header's frame
    count, which a damaged file sets to billions."""
    while len(block := f.read(_DECODE_BLOCK, dtype="float32", always_2d=True)):
        yield block


def _mono(blocks: Iterable[np.ndarray], frames: int) -> np.ndarray:
    """The blocks' channels averaged into one float32 signal; `frames` (a header's claim) sizes the buffer."""
    out = np.empty(min(max(int(frames), 0), _DECODE_PREALLOCATE), dtype=np.float32)
    n = 0
    for block in blocks:
        mono = block.mean(axis=1, dtype=np.float32) if block.shape[1] > 1 else block[:, 0]
        if n + len(mono) > len(out):  # frame counts of compressed formats can be estimates
            out = np.concatenate([out[:n], np.empty(max(len(mono), len(out) // 4), np.float32)])
        out[n : n + len(mono)] = mono
        n += len(mono)
    return out[:n]


def _decode_other(path: Path, soundfile_error: Exception) -> tuple[int, int, np.ndarray]:
    """(rate, channels, mono) of a file libsndfile cannot read; a DanceNetError naming the decoder's complaint
    when no decoder can."""
    decode = _other_decoder()
    if decode is None:
        raise DanceNetError(
            f"cannot decode {path.name} as audio ({_one_line(soundfile_error)}); supported formats: "
            f"{', '.join(SUPPORTED_FORMATS)}, and {', '.join(FFMPEG_FORMATS)} with imageio-ffmpeg "
            f"(`pip install imageio-ffmpeg`); or convert it with e.g. `ffmpeg -i {path.name} song.wav`"
        )
    try:
        return decode(path)
    except DanceNetError:
        raise
    except Exception as e:  # ffmpeg's own complaint, imageio-ffmpeg without its binary, aud.error
        raise DanceNetError(
            f"cannot decode {path.name} as audio ({_one_line(e)}); supported formats: "
            f"{', '.join(SUPPORTED_FORMATS + FFMPEG_FORMATS)}; convert it with e.g. `ffmpeg -i {path.name} song.wav`"
        ) from e


def _other_decoder() -> Callable[[Path], tuple[int, int, np.ndarray]] | None:
    """imageio-ffmpeg's bundled ffmpeg where it is installed (it never downloads one), else Blender's `aud`
    (importable only inside Blender or after `import bpy`): the extension leaves the 23-68 MB wheel out."""
    try:
        import imageio_ffmpeg
    except ImportError:
        pass
    else:
        return lambda path: _decode_ffmpeg(path, imageio_ffmpeg.get_ffmpeg_exe())
    try:
        import aud
    except ImportError:
        return None
    return lambda path: _decode_aud(path, aud)


def _decode_ffmpeg(path: Path, ffmpeg: str) -> tuple[int, int, np.ndarray]:
    """The first audio stream as 32-bit float WAV on a pipe, read block by block; ffmpeg's messages go to a
    file, not a pipe that could fill up and stall it."""
    command = [ffmpeg, "-nostdin", "-v", "error", "-i", str(path), "-map", "0:a:0", "-c:a", "pcm_f32le",
               "-f", "wav", "-map_metadata", "-1", "-fflags", "+bitexact", "pipe:1"]  # fmt: skip
    with tempfile.TemporaryFile() as log, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log) as proc:
        try:
            rate, channels = _wav_header(proc.stdout)
            if rate is not None:
                _check_rate(path, rate)
            mono = np.empty(0, np.float32) if rate is None else _mono(_pipe_blocks(proc.stdout, channels), 0)
        except BaseException:  # a bad rate, Ctrl-C: ffmpeg would go on decoding into a pipe nobody reads
            proc.kill()
            raise
        finally:
            proc.stdout.close()
        if proc.wait():
            log.seek(0)
            lines = log.read().decode(errors="replace").strip().splitlines() or [f"exit status {proc.returncode}"]
            raise RuntimeError(f"ffmpeg: {lines[-1].strip()}")
    return rate or 0, channels, mono


def _wav_header(pipe: IO[bytes]) -> tuple[int | None, int]:
    """(rate, channels) from a streamed WAV's chunks up to `data`; (None, 0) when nothing came."""
    riff = pipe.read(12)
    if len(riff) < 12:
        return None, 0
    rate, channels = None, 0
    while len(head := pipe.read(8)) == 8:
        size = int.from_bytes(head[4:], "little")
        if head[:4] == b"data":
            break
        body = pipe.read(size + size % 2)
        if head[:4] == b"fmt ":
            channels, rate = int.from_bytes(body[2:4], "little"), int.from_bytes(body[4:8], "little")
    return (rate, channels) if channels else (None, 0)


def _pipe_blocks(pipe: IO[bytes], channels: int) -> Iterator[np.ndarray]:
    frame = 4 * channels
    rest = b""
    while chunk := pipe.read(_DECODE_BLOCK * frame):
        chunk = rest + chunk
        whole = len(chunk) // frame * frame
        rest = chunk[whole:]
        yield np.frombuffer(chunk[:whole], dtype="<f4").reshape(-1, channels)


def _decode_aud(path: Path, aud: ModuleType) -> tuple[int, int, np.ndarray]:
    """Blender's decoder, for the extension (no ffmpeg wheel): it decodes the whole file at once."""
    sound = aud.Sound(str(path))
    rate, channels = (int(v) for v in sound.specs)
    _check_rate(path, rate)
    data = np.asarray(sound.data(), dtype=np.float32)
    return rate, channels, _mono([data.reshape(len(data), -1)], len(data))


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split()) or type(e).__name__
