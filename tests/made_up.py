"""Made-up inputs for the tests: music (click tracks, chords, analyses with known beats and bars), a small
motion, and where the real data lives (tests that need it skip cleanly when it is absent)."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import numpy as np
import soundfile as sf

from dancenet_core.motion import Motion
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE
from dancenet_core.music.features import MusicAnalysis

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    return Path(os.environ.get("DANCENET_DATA", REPO.parent / "shared" / "data"))


def click_track(bpm: float, dur: float = 12.0, offset: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Clicks (noise plus a tone, decaying in ~4 ms) on every beat, louder and higher on every 4th."""
    rng = np.random.default_rng(int(bpm))
    x = np.zeros(int(dur * MADMOM_SAMPLE_RATE), np.float32)
    times = np.arange(offset, dur - 0.05, 60.0 / bpm)
    n = int(0.03 * MADMOM_SAMPLE_RATE)
    t = np.arange(n) / MADMOM_SAMPLE_RATE
    env = np.exp(-t / 0.004)
    for i, when in enumerate(times):
        s = int(round(when * MADMOM_SAMPLE_RATE))
        amp, freq = (0.9, 1500) if i % 4 == 0 else (0.5, 1000)
        burst = amp * env * (0.5 * rng.standard_normal(n) + np.sin(2 * np.pi * freq * t))
        x[s : s + n] += burst[: len(x) - s]
    return x, times


def encoded_click_track(folder: Path, formats: tuple[str, ...], bpm: float = 120) -> tuple[Path, list[Path]]:
    """A click track as WAV and encoded by imageio-ffmpeg's ffmpeg into each format ("m4a": AAC; "mp4": AAC
    beside an H.264 picture), for the decoders that libsndfile lacks."""
    import imageio_ffmpeg

    wav = folder / "clicks.wav"
    sf.write(str(wav), np.stack([click_track(bpm)[0]] * 2, axis=1), MADMOM_SAMPLE_RATE)
    encoded = []
    for ext in formats:
        video = ["-f", "lavfi", "-i", "color=size=64x64:rate=10", "-shortest", "-c:v", "libx264"]
        video = video if ext == "mp4" else []
        out = folder / f"clicks.{ext}"
        subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-y", "-i", str(wav), *video, "-c:a", "aac",
                        str(out)], check=True)  # fmt: skip
        encoded.append(out)
    return wav, encoded


def music(dur: float, seed: int = 0) -> np.ndarray:
    """Chords on a 120 BPM pulse with a little noise: enough structure for every network."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(dur * MADMOM_SAMPLE_RATE))) / MADMOM_SAMPLE_RATE
    root = 220 * 2 ** (np.floor(t / 2) % 4 * 5 / 12)
    pulse = 0.5 + 0.5 * np.exp(-(t % 0.5) / 0.05)
    tone = sum(np.sin(2 * np.pi * root * r * t) for r in (1, 1.26, 1.5)) / 3
    return (0.4 * pulse * tone + 0.01 * rng.standard_normal(len(t))).astype(np.float32)


def small_motion(frames: int = 20) -> Motion:
    rng = np.random.default_rng(0)
    rot = 0.2 * rng.standard_normal((frames, 55, 3))
    root = np.stack([np.zeros(frames), np.full(frames, 0.9), np.linspace(0, 1, frames)], -1)
    return Motion(rot, root, 25.0)


def analysis(features: np.ndarray, beat_s: float = 0.5, bar: int = 4) -> MusicAnalysis:
    """An analysis of `features` (10 fps) with a beat every `beat_s` seconds and a downbeat every `bar` beats."""
    beats = np.arange(0.0, len(features) / 10, beat_s)
    return MusicAnalysis(features, beats, beats[::bar], 60 / beat_s, len(features) / 10)


def clicks(num_frames: int, period: int, bar: int) -> np.ndarray:
    """Features with a beat every `period` frames, a downbeat every `bar` beats (activations peaking over three
    frames, as madmom's do at 10 fps) and some chroma."""
    x = np.zeros((num_frames, 15), np.float32)
    for col, step in ((12, period), (13, period * bar)):
        x[::step, col] = 1.0
        x[1::step, col] = x[step - 1 :: step, col] = 0.5
    x[:, :12] = np.random.default_rng(1).random((num_frames, 12))
    return x


def peak_frames(column: np.ndarray) -> np.ndarray:
    """Local maxima above a quarter of the full height: beats in an (interpolated, scaled) activation."""
    c = np.pad(column, 1)
    return np.flatnonzero((c[1:-1] > 0.25) & (c[1:-1] >= c[:-2]) & (c[1:-1] > c[2:]))


def peaks(column: np.ndarray) -> int:
    return len(peak_frames(column))


def as_a_terminal_signals_it() -> None:
    """In a test's child process: SIGHUP and SIGINT back to their default actions, as a command started from a
    terminal has them. A suite started under `nohup` ignores SIGHUP, and one started in the background by a shell
    without job control (`make test &` in a script) ignores SIGINT; a child inherits an ignored signal (Python then
    never raises KeyboardInterrupt), so a test of what a hang-up or Ctrl-C does would see the command run on."""
    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_DFL)



def arranged_training_song(path: Path, form: str = "ABACAB") -> Path | None:
    """`evaluation.form.arranged_song` from the data the tests read: a song whose form is known, or None."""
    from dancenet_core.evaluation.form import arranged_song

    return arranged_song(data_root(), path, form)


def read_video(path: Path) -> tuple[dict, np.ndarray]:
    """A video file read back by imageio-ffmpeg's ffmpeg: its metadata (size, fps, duration) and its frames
    [N, H, W, 3] uint8, so a test checks what a viewer would see, not that some bytes were written."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    return meta, np.stack([np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader])


def click_song(path: Path, seconds: float, bpm: float = 120.0, bar: int = 0, rate: int = 22050,
               subtype: str | None = None) -> Path:
    """A song file for the command line and the add-on: a 10-ms click on every beat over a quiet 220 Hz tone
    (every `bar`-th click louder, the bar's first beat; 0: all alike), in the format its suffix names."""
    t = np.arange(int(seconds * rate)) / rate
    beat = np.floor(t * bpm / 60.0)
    loud = np.where((bar > 0) & (beat % max(bar, 1) == 0), 1.6, 1.0)
    y = 0.1 * np.sin(2 * np.pi * 220 * t) + 0.5 * loud * (np.mod(t, 60.0 / bpm) < 0.01)
    sf.write(path, y.astype(np.float32), rate, subtype=subtype)
    return path


class CountingChild:
    """A stand-in for the warm-up's compiling process (dancenet_core.warmup._CHILD): it counts into a file for a
    minute, so a test sees whether it runs or is stopped, and names the kernels a click waits for (as written to
    numba's cache) once `release` is called."""

    def __init__(self, folder: Path) -> None:
        self.file, self.go = folder / "count", folder / "release"
        self.code = ("import os, time\nfor i in range(3000):\n"
                     f"    open({str(self.file)!r}, 'w').write(str(i))\n"
                     f"    if os.path.exists({str(self.go)!r}) and not os.path.exists({str(self.go)!r} + 'd'):\n"
                     f"        open({str(self.go)!r} + 'd', 'w').close()\n"
                     "        print('networks', flush=True)\n        print('beat decode', flush=True)\n"
                     "    time.sleep(0.02)")  # fmt: skip

    def release(self) -> None:
        self.go.touch()

    def count(self) -> int:
        try:
            return int(self.file.read_text() or -1)
        except FileNotFoundError:
            return -1

    def frozen(self, for_s: float = 0.4) -> bool:
        """No count for `for_s` (after a moment for a signal in flight to land)."""
        import time

        time.sleep(0.1)
        before = self.count()
        time.sleep(for_s)
        return self.count() == before

    def counts(self, within_s: float = 20.0) -> bool:
        """A new count within `within_s` (generous: a loaded machine may start it slowly)."""
        import time

        before, end = self.count(), time.monotonic() + within_s
        while time.monotonic() < end:
            if self.count() > before:
                return True
            time.sleep(0.02)
        return False
