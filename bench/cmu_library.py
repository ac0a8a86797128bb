"""The shipped CMU library (the `library` engine's default, for a user with no library of their own) on songs of
other styles and tempi: `dancenet generate SONG --engine library` as a user runs it, on the example song (a 3/4
waltz at 84 BPM) and on the first 60 s of six Dance with Melody songs whose tempi (as the beat tracker reads them)
spread from the slowest to the fastest (the songs, not their dancers; the library's clips are salsa, swing, latin,
Indian and modern dance). Prints JSON per song and over all: the dance's Beat Align Score against its own song's
beats and its ratio to the score against the other songs' beats (a dance that follows its song scores well above
1), its cuts, the largest step a cut made against the capture's own largest (each joint's step over its 99th
percentile), how long the dance stays with one clip between cuts (in the song's bars), and the largest real-time
warp.

    OMP_NUM_THREADS=1 .venv/bin/python bench/cmu_library.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from dancenet_core.data.dance_with_melody import read_manifest
from dancenet_core.environment import default_data_dir
from dancenet_core.evaluation.metrics import beat_align_score, own_song_bas_ratio
from dancenet_core.generate import generate_dance
from dancenet_core.library.store import load_default
from dancenet_core.request import DanceRequest
from dancenet_core.skeleton import BODY_JOINTS

SONG_S = 60.0
SONGS = 6
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "example_song.ogg"


def songs() -> list[Path]:
    """The example song and SONGS Dance with Melody songs at evenly spread ranks of their tempo."""
    from dancenet_core.music.features import analyze_music

    rows = [r for r in read_manifest(default_data_dir()) if r.audio.is_file()]
    tempo = sorted((analyze_music(r.audio).tempo_bpm, r.seq, r.audio) for r in rows)
    picks = np.linspace(0, len(tempo) - 1, SONGS).round().astype(int)
    return [EXAMPLE] + [tempo[i][2] for i in picks]


def main() -> int:
    library = load_default()
    capture_largest = float(library.step_ratios.max())
    out, positions, beats = [], [], []
    for song in songs():
        result = generate_dance(DanceRequest(song=song, engine="library", end_s=SONG_S))
        motion, detail = result.motions[0], result.details[0]
        pos = motion.positions()[:, :BODY_JOINTS]
        ibi = float(np.median(np.diff(result.beat_times)))
        downs = np.flatnonzero(np.isin(result.beat_times, result.downbeat_times))
        meter = int(np.median(np.diff(downs))) if len(downs) > 1 else 4
        positions.append(pos)
        beats.append(result.beat_times)
        out.append({"song": song.name, "tempo_bpm": round(result.tempo_bpm, 1), "meter": meter,
                    "seconds": round(motion.duration, 1),
                    "bas": round(beat_align_score(pos, motion.fps, result.beat_times), 3),
                    "cuts": detail["cuts"], "figures": detail["figures"],
                    "mean_run_bars": round(motion.duration / (detail["cuts"] + 1) / (meter * ibi), 2),
                    "max_cut_step": detail["max_cut_step"], "max_warp": detail["max_warp"]})
    summary = {"capture_largest_step": round(capture_largest, 3),
               "bas_min": min(r["bas"] for r in out),
               "bas_own_over_other": round(own_song_bas_ratio(positions, 25.0, beats), 3),
               "max_cut_step": max(r["max_cut_step"] for r in out),
               "mean_run_bars_min": min(r["mean_run_bars"] for r in out),
               "max_warp": max(r["max_warp"] for r in out)}
    print(json.dumps({"songs": out, "all": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
