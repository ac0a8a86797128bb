"""The weight-free music analysis (`music/weightfree.py`, the commercial mode's) measured, printed as JSON:

- on made-up songs with known beats (`scripts/synth_songs.py`: 60-200 BPM, 3/4 and 4/4, straight and swung, with
  drums and without): the beat F-measure (70 ms), the share whose tempo has the right octave (within 4 % of the
  song's, not half or double it), and the downbeat F-measure (70 ms); the same for the default analysis (madmom's
  networks) with --default-too;
- on the Dance with Melody songs (`$DANCENET_DATA/dance_with_melody`, the default analysis from the feature cache
  or computed): the beat F-measure of the weight-free beats against the default analysis' beats, per song and the
  median, the time-stretched T_5, C_7, C_8 and C_9 included (their songs are not stretched, only their motion);
- the time to analyse a 3-minute song (a made-up one, decoding included, cold) and the default analysis' time on
  the same song in the same run (2 workers), as a ratio.

    OMP_NUM_THREADS=1 .venv/bin/python bench/weightfree_beats.py [--seconds 30] [--no-dwm] [--default-too]

F-measures are madmom's (`madmom.evaluation.beats`, BSD code: no model file is opened by it).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from synth_songs import SongSpec, synth_song, write_song  # noqa: E402

from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.music.audio import Audio, load_audio  # noqa: E402
from dancenet_core.music.weightfree import analyze_audio_weightfree  # noqa: E402

WINDOW_S = 0.07
BPMS = (60, 66, 72, 80, 84, 90, 96, 104, 110, 120, 128, 136, 144, 150, 160, 175, 190, 200)


def fmeasure(detections: np.ndarray, annotations: np.ndarray) -> float:
    """The F-measure of `detections` against `annotations` (one-to-one matches within 70 ms)."""
    from madmom.evaluation.onsets import onset_evaluation

    tp, fp, _tn, fn, _errors = onset_evaluation(np.asarray(detections, float), np.asarray(annotations, float),
                                                window=WINDOW_S)
    return 2 * len(tp) / max(2 * len(tp) + len(fp) + len(fn), 1)


def made_up_specs(seconds: float) -> list[SongSpec]:
    """Every tempo of BPMS in 3/4 and 4/4, straight and swung, with drums and without (the seed varies)."""
    return [SongSpec(bpm, meter, swing, seconds, seed=i, drums=drums)
            for i, (bpm, meter, swing, drums) in enumerate((b, m, s, d) for b in BPMS for m in (3, 4)
                                                             for s in (False, True) for d in (True, False))]


def made_up(seconds: float, default_too: bool) -> dict:
    rows = []
    for spec in made_up_specs(seconds):
        x, beats, downs = synth_song(spec)
        found = {"weightfree": analyze_audio_weightfree(Audio(x.astype(np.float32), 44100, 44100, 1, Path(spec.name)))}
        if default_too:
            from dancenet_core.music.features import analyze_audio
            found["default"] = analyze_audio(Audio(x.astype(np.float32), 44100, 44100, 1, Path(spec.name)), workers=1)
        row = {"song": spec.name}
        for name, a in found.items():
            row[name] = {"beat_f": round(fmeasure(a.beat_times, beats), 3),
                         "octave_right": bool(abs(a.tempo_bpm / spec.bpm - 1) < 0.04),
                         "tempo_bpm": round(a.tempo_bpm, 1),
                         "downbeat_f": round(fmeasure(a.downbeat_times, downs), 3)}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    return {"songs": len(rows), **{name: _summary([r[name] for r in rows]) for name in rows[0] if name != "song"},
            "worst": sorted(rows, key=lambda r: r["weightfree"]["beat_f"] + r["weightfree"]["downbeat_f"])[:8]}


def _summary(rows: list[dict]) -> dict:
    return {"beat_f_mean": round(float(np.mean([r["beat_f"] for r in rows])), 3),
            "beat_f_median": round(float(np.median([r["beat_f"] for r in rows])), 3),
            "octave_right_share": round(float(np.mean([r["octave_right"] for r in rows])), 3),
            "downbeat_f_mean": round(float(np.mean([r["downbeat_f"] for r in rows])), 3)}


def dance_with_melody() -> dict:
    from dancenet_core.music.features import analyze_music

    rows = {}
    for song in sorted((default_data_dir() / "dance_with_melody").glob("DANCE_*.ogg")):
        default = analyze_music(song)
        mine = analyze_audio_weightfree(load_audio(song))
        rows[song.stem] = {"beat_f": round(fmeasure(mine.beat_times, default.beat_times), 3),
                           "tempo_bpm": round(mine.tempo_bpm, 1), "default_tempo_bpm": round(default.tempo_bpm, 1),
                           "downbeat_f": round(fmeasure(mine.downbeat_times, default.downbeat_times), 3)}
        print(json.dumps({song.stem: rows[song.stem]}), file=sys.stderr, flush=True)
    f = [r["beat_f"] for r in rows.values()]
    return {"songs": len(rows), "beat_f_median": round(float(np.median(f)), 3),
            "beat_f_mean": round(float(np.mean(f)), 3),
            "downbeat_f_median": round(float(np.median([r["downbeat_f"] for r in rows.values()])), 3),
            "tempo_octave_agrees_share": round(float(np.mean(
                [abs(r["tempo_bpm"] / r["default_tempo_bpm"] - 1) < 0.04 for r in rows.values()])), 3),
            "per_song": rows}


def speed(rounds: int) -> dict:
    """Cold analyses of one 3-minute made-up song: the best of `rounds` for each, interleaved."""
    from dancenet_core.music.features import analyze_music
    from dancenet_core.music.weightfree import analyze_music_weightfree

    with tempfile.TemporaryDirectory() as tmp:
        song = Path(tmp) / "three_minutes.ogg"
        write_song(SongSpec(126, 4, False, 180.0, seed=7), song)
        mine, default = [], []
        for _ in range(rounds):
            t = time.perf_counter()
            analyze_music_weightfree(song, use_cache=False)
            mine.append(time.perf_counter() - t)
            t = time.perf_counter()
            analyze_music(song, use_cache=False, workers=2)
            default.append(time.perf_counter() - t)
    return {"song_s": 180.0, "weightfree_s": round(min(mine), 3), "default_s": round(min(default), 3),
            "weightfree_over_default": round(min(mine) / min(default), 4)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="length of each made-up song")
    parser.add_argument("--no-dwm", action="store_true", help="leave out the Dance with Melody songs")
    parser.add_argument("--no-speed", action="store_true", help="leave out the timing")
    parser.add_argument("--default-too", action="store_true", help="the default analysis on the made-up songs too")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    out = {"made_up": made_up(args.seconds, args.default_too)}
    if not args.no_dwm:
        out["dance_with_melody_vs_default"] = dance_with_melody()
    if not args.no_speed:
        out["speed_3min"] = speed(args.rounds)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
