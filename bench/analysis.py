"""Music analysis speed: seconds per minute of audio, cold (empty cache) and cached, and peak memory; and,
in the same run, the cold analysis with madmom's own onset and downbeat processors and its own downbeat DBN
(the path before the compiled networks and decode) for the speed-up ratio; each cold path runs twice,
interleaved, and its best time counts.

Usage: `python bench/analysis.py [--song PATH] [--synthetic-minutes M] [--workers N] [--no-baseline]`.
Without --song it takes DANCE_W_1 from $DANCENET_DATA (default <repo>/../shared/data), else a synthetic
song. Prints JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile as sf

from dancenet_core.music import features
from dancenet_core.music.audio import MADMOM_SAMPLE_RATE
from dancenet_core.music.features import analyze_music

REPO = Path(__file__).resolve().parents[1]


def synthetic_song(path: Path, minutes: float) -> Path:
    """Chords on a 120 BPM pulse, written in one-minute pieces so that even 30 minutes stay cheap."""
    sr = MADMOM_SAMPLE_RATE
    rng = np.random.default_rng(0)
    with sf.SoundFile(str(path), "w", samplerate=sr, channels=1, format="FLAC") as f:
        for m in range(int(np.ceil(minutes))):
            t = m * 60 + np.arange(int(min(60, 60 * (minutes - m)) * sr)) / sr
            root = 220 * 2 ** (np.floor(t / 2) % 4 * 5 / 12)
            tone = sum(np.sin(2 * np.pi * root * r * t) for r in (1, 1.26, 1.5)) / 3
            pulse = 0.5 + 0.5 * np.exp(-(t % 0.5) / 0.05)
            f.write((0.4 * pulse * tone + 0.01 * rng.standard_normal(len(t))).astype(np.float32))
    return path


def madmom_processors() -> tuple:
    """The analysis' processors with madmom's own RNNOnsetProcessor and RNNDownBeatProcessor in place of
    the compiled pair: what the analysis ran before."""
    from madmom.features.downbeats import RNNDownBeatProcessor
    from madmom.features.onsets import RNNOnsetProcessor

    onset, beat = RNNOnsetProcessor(), RNNDownBeatProcessor()
    return (lambda sig: (onset(sig), beat(sig)), *compiled_processors()[1:])


def madmom_tracker():
    """madmom's own downbeat DBN, its Viterbi decode not compiled: what the analysis ran before."""
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor

    return DBNDownBeatTrackingProcessor(beats_per_bar=list(features.BEATS_PER_BAR), fps=features.ACT_FPS)


compiled_processors, compiled_tracker = features._processors, features._tracker


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--song", help="audio file to analyse")
    parser.add_argument("--synthetic-minutes", type=float, help="analyse a synthetic song this long instead")
    parser.add_argument("--workers", type=int, help="worker processes (default: up to 2)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the run with madmom's processors")
    args = parser.parse_args()
    data = Path(os.environ.get("DANCENET_DATA", REPO.parent / "shared" / "data"))
    with tempfile.TemporaryDirectory() as tmp:
        if args.synthetic_minutes:
            song, kind = synthetic_song(Path(tmp) / "synthetic.flac", args.synthetic_minutes), "synthetic"
        elif args.song:
            song, kind = Path(args.song), "given"
        elif (data / "dance_with_melody" / "DANCE_W_1.ogg").is_file():
            song, kind = data / "dance_with_melody" / "DANCE_W_1.ogg", "real"
        else:
            song, kind = synthetic_song(Path(tmp) / "synthetic.flac", 3.0), "synthetic (no data found)"
        # Each path twice, interleaved (ours, madmom's, ours, madmom's), best of two: the process's and the
        # machine's one-time costs (this VM faults fresh memory in slowly the first time) fall on neither side.
        cold, baseline = [], []
        for rep in range(1 if args.no_baseline else 2):
            cache = Path(tmp) / f"cache{rep}"
            t0 = time.perf_counter()
            a = analyze_music(song, cache_dir=cache, workers=args.workers)
            cold.append(time.perf_counter() - t0)
            if not args.no_baseline:
                features._processors, features._tracker = madmom_processors, madmom_tracker  # forked workers inherit
                t0 = time.perf_counter()
                b = analyze_music(song, use_cache=False, workers=args.workers)
                baseline.append(time.perf_counter() - t0)
                features._processors, features._tracker = compiled_processors, compiled_tracker
        t0 = time.perf_counter()
        analyze_music(song, cache_dir=cache, workers=args.workers)
        warm = time.perf_counter() - t0
        cold, baseline = min(cold), min(baseline) if baseline else None
        if baseline is not None:
            beats_same = len(b.beat_times) == len(a.beat_times) and bool(np.allclose(b.beat_times, a.beat_times))
            max_feature_diff = float(np.abs(b.features - a.features).max())
    minutes = a.duration_s / 60
    rss = {
        who: resource.getrusage(r).ru_maxrss / 1024
        for who, r in (("main", resource.RUSAGE_SELF), ("largest_worker", resource.RUSAGE_CHILDREN))
    }
    print(
        json.dumps(
            {
                "song": song.name,
                "kind": kind,
                "audio_minutes": round(minutes, 2),
                "frames": list(a.features.shape),
                "beats": len(a.beat_times),
                "tempo_bpm": round(a.tempo_bpm, 1),
                "cold_s": round(cold, 2),
                "cached_s": round(warm, 4),
                "cold_s_per_audio_min": round(cold / minutes, 2),
                "cached_s_per_audio_min": round(warm / minutes, 5),
                "cold_over_cached": round(cold / warm, 1),
                **(
                    {}
                    if baseline is None
                    else {
                        "madmom_processors_cold_s_per_audio_min": round(baseline / minutes, 2),
                        "speedup_over_madmom_processors": round(baseline / cold, 2),
                        "beats_same_as_madmom_processors": beats_same,
                        "max_feature_diff_vs_madmom_processors": round(max_feature_diff, 6),
                    }
                ),
                "peak_rss_mib": {k: round(v) for k, v in rss.items()},
                "workers": args.workers or min(2, os.cpu_count() or 1),
                "cpu": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                "load_average_1min": round(os.getloadavg()[0], 2),
            },
            indent=1,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
