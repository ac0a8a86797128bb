"""Synthesise the bundled example song (made by the project, so free to ship): a 3/4 waltz at 84 BPM.

Deterministic: running it again writes the same samples. `make demo` dances to its output.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import soundfile as sf

SR = 44100
BPM = 84.0
BARS = 24


def tone(freq: float, dur: float, amp: float, decay: float) -> np.ndarray:
    t = np.arange(int(dur * SR)) / SR
    env = np.exp(-t / decay) * np.minimum(1.0, t / 0.01)
    return amp * env * (np.sin(2 * np.pi * freq * t) + 0.3 * np.sin(4 * np.pi * freq * t))


def main(out: Path) -> None:
    beat = 60.0 / BPM
    total = BARS * 3 * beat + 2.0
    song = np.zeros(int(total * SR))
    rng = np.random.default_rng(0)
    # I - IV - V - I in C major, one chord per bar; root on beat 1, chord on beats 2 and 3.
    chords = [(130.81, 164.81, 196.0), (174.61, 220.0, 261.63), (196.0, 246.94, 293.66), (130.81, 164.81, 196.0)]
    melody = [523.25, 587.33, 659.25, 698.46, 783.99, 698.46, 659.25, 587.33]
    for bar in range(BARS):
        chord = chords[bar % 4]
        for b in range(3):
            start = int((bar * 3 + b) * beat * SR)
            if b == 0:
                note = tone(chord[0] / 2, 0.6, 0.5, 0.25)
                kick = tone(55.0, 0.25, 0.8, 0.06)
                song[start : start + len(note)] += note
                song[start : start + len(kick)] += kick
            else:
                for f in chord:
                    n = tone(f, 0.35, 0.18, 0.12)
                    song[start : start + len(n)] += n
                hat = rng.normal(0, 0.08, int(0.05 * SR)) * np.exp(-np.arange(int(0.05 * SR)) / 400)
                song[start : start + len(hat)] += hat
            m = tone(melody[(bar * 3 + b) % len(melody)], beat * 0.9, 0.15, 0.4)
            song[start : start + len(m)] += m
    song = 0.8 * song / np.abs(song).max()
    # libsndfile's Vorbis encoder crashes on very large single writes: feed it in blocks.
    with sf.SoundFile(out, "w", SR, 1, format="OGG", subtype="VORBIS") as f:
        for i in range(0, len(song), 1 << 15):
            f.write(song[i : i + (1 << 15)].astype(np.float32))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("examples/example_song.ogg"))
