"""Songs with known beats for measuring dances at any tempo: drums, bass and chords, 3/4 or 4/4, straight or swung,
60-200 BPM. The Dance with Melody songs cover about 80-130 BPM; a user's songs go from a 60-BPM ballad to a
200-BPM electronic track, and a dance has to keep its energy, its floor and its song's beats over all of them.

Each song is deterministic (its seed): kick on the downbeat (and the middle of a 4/4 bar), snare on the backbeats,
hi-hats on the off-beats (swung: played at two thirds of the beat), a bass note on every beat following a
four-chord loop, the chord on the beats the bass leaves. `synth_song` returns the samples and the beat and
downbeat times it placed, so a measurement can check the beat tracker as well as the dance.

    .venv/bin/python scripts/synth_songs.py OUT_DIR [--bpm 60 90 120 150 200] [--seconds 60]

writes `OUT_DIR/song_<bpm>_<meter>_<straight|swing>.ogg` and a `songs.json` with the known beats.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile as sf

SR = 44100
# I - vi - IV - V in C (root, third, fifth in Hz)
CHORDS = ((130.81, 164.81, 196.0), (110.0, 130.81, 164.81), (174.61, 220.0, 261.63), (196.0, 246.94, 293.66))


@dataclass(frozen=True)
class SongSpec:
    bpm: float
    meter: int = 4
    swing: bool = False
    seconds: float = 60.0
    seed: int = 0
    drums: bool = True  # False: bass and chords alone (the beat in the harmony, no percussion)

    @property
    def name(self) -> str:
        return f"song_{self.bpm:g}_{self.meter}-4_{'swing' if self.swing else 'straight'}" + \
            ("" if self.drums else "_nodrums")


def _tone(freq: float, dur: float, amp: float, decay: float) -> np.ndarray:
    t = np.arange(int(dur * SR)) / SR
    env = np.exp(-t / decay) * np.minimum(1.0, t / 0.005)
    return amp * env * (np.sin(2 * np.pi * freq * t) + 0.3 * np.sin(4 * np.pi * freq * t))


def _kick(amp: float) -> np.ndarray:
    t = np.arange(int(0.25 * SR)) / SR
    freq = 50.0 + 90.0 * np.exp(-t / 0.03)  # a falling pitch: the thump of a kick drum
    return amp * np.exp(-t / 0.08) * np.sin(2 * np.pi * np.cumsum(freq) / SR)


def _noise(rng: np.random.Generator, dur: float, amp: float, decay: float) -> np.ndarray:
    n = int(dur * SR)
    return amp * rng.normal(0.0, 1.0, n) * np.exp(-np.arange(n) / (decay * SR))


def _add(song: np.ndarray, at_s: float, sound: np.ndarray) -> None:
    i = int(round(at_s * SR))
    if i < len(song):
        song[i : i + len(sound)] += sound[: len(song) - i]


def _drums(song: np.ndarray, rng: np.random.Generator, meter: int, pos: int, at_s: float, off_s: float) -> None:
    """One beat's drums: kick on the downbeat (and the middle of a 4/4 bar), snare on the backbeats, hi-hats on
    the beat and the off-beat."""
    if pos == 0 or (meter == 4 and pos == 2):
        _add(song, at_s, _kick(0.9))
    if (meter == 4 and pos in (1, 3)) or (meter == 3 and pos in (1, 2)):
        _add(song, at_s, _noise(rng, 0.15, 0.35 if meter == 4 else 0.2, 0.04))
    _add(song, at_s, _noise(rng, 0.05, 0.08, 0.008))
    _add(song, off_s, _noise(rng, 0.05, 0.06, 0.008))


def synth_song(spec: SongSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mono samples at SR, beat times [s], downbeat times [s]) of the song `spec` describes."""
    rng = np.random.default_rng(spec.seed)
    beat = 60.0 / spec.bpm
    first = 0.5  # the first downbeat (a little silence before it, as in a recording)
    n_beats = int((spec.seconds - first) / beat)
    beats = first + beat * np.arange(n_beats)
    song = np.zeros(int(spec.seconds * SR) + SR)
    off = (2.0 / 3.0) if spec.swing else 0.5  # where the off-beat hi-hat falls within the beat
    for k, t in enumerate(beats):
        pos, bar = k % spec.meter, k // spec.meter
        chord = CHORDS[bar % len(CHORDS)]
        if spec.drums:
            _drums(song, rng, spec.meter, pos, t, t + off * beat)
        bass = chord[0] / 2 if pos % 2 == 0 else chord[2] / 2
        _add(song, t, _tone(bass, 0.9 * beat, 0.45, 0.3 * beat + 0.05))
        if pos != 0:
            for f in chord:
                _add(song, t, _tone(f, 0.8 * beat, 0.12, 0.25))
    song = song[: int(spec.seconds * SR)]
    return 0.8 * song / np.abs(song).max(), beats, beats[:: spec.meter]


def write_song(spec: SongSpec, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The song written as Ogg Vorbis at `path`; returns its beat and downbeat times."""
    samples, beats, downs = synth_song(spec)
    path.parent.mkdir(parents=True, exist_ok=True)
    with sf.SoundFile(path, "w", SR, 1, format="OGG", subtype="VORBIS") as f:
        for i in range(0, len(samples), 1 << 15):  # libsndfile's Vorbis encoder crashes on large single writes
            f.write(samples[i : i + (1 << 15)].astype(np.float32))
    return beats, downs


# A spread of the songs users dance to: slow to fast, 3/4 and 4/4, straight and swung.
DEFAULT_SPECS = (SongSpec(60, 4), SongSpec(84, 3), SongSpec(100, 4, swing=True), SongSpec(128, 4),
                 SongSpec(150, 3, swing=True), SongSpec(175, 4), SongSpec(200, 4))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    known = {}
    for spec in DEFAULT_SPECS:
        spec = SongSpec(spec.bpm, spec.meter, spec.swing, args.seconds, spec.seed)
        beats, downs = write_song(spec, args.out / f"{spec.name}.ogg")
        known[spec.name] = {"bpm": spec.bpm, "meter": spec.meter, "swing": spec.swing,
                            "beats": beats.round(4).tolist(), "downbeats": downs.round(4).tolist()}
    (args.out / "songs.json").write_text(json.dumps(known))
    print(json.dumps({k: {"bpm": v["bpm"], "meter": v["meter"], "swing": v["swing"]} for k, v in known.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
