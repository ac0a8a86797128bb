"""Generation speed and memory, printed as JSON (ratios measured in the same run).

- frames per second of cached generation and of the naive way (the full stack over the last
  receptive-field frames for every new frame, as the authors' release does), and their ratio;
- seconds to dance a 3-minute song once its music analysis is cached (style, music encoder, sampling,
  decoding, foot clean-up), and the cold analysis it needs the first time;
- peak resident memory of a whole `generate_dance` for a 10-minute song, in a fresh process.

    .venv/bin/python bench/generation.py [--weights PATH] [--skip-memory]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def synth_song(path: Path, seconds: float, bpm: float = 120.0, sr: int = 22050) -> None:
    """A song made here (clicks on the beat over a chord), so the benchmark needs no data."""
    import soundfile as sf

    t = np.arange(int(seconds * sr)) / sr
    y = 0.05 * (np.sin(2 * np.pi * 220 * t) + np.sin(2 * np.pi * 277.2 * t) + np.sin(2 * np.pi * 329.6 * t))
    click = np.hanning(600)[300:] * np.sin(2 * np.pi * 1500 * np.arange(300) / sr)
    for beat in np.arange(0.0, seconds - 0.1, 60.0 / bpm):
        i = int(beat * sr)
        y[i : i + 300] += 0.5 * click
    with sf.SoundFile(path, "w", sr, 1, format="WAV") as f:
        f.write(y.astype(np.float32))


def sampler_speed(weights: str | None) -> dict:
    from dancenet_core.generate import load_bundle
    from dancenet_core.model.sampler import CachedSampler, Sampling, music_conditioning, naive_run

    bundle = load_bundle(weights)
    model, rf = bundle.model, bundle.model.cfg.receptive_field
    rng = np.random.default_rng(0)
    frames = 3000
    cond = music_conditioning(model, rng.normal(size=(frames, 15)).astype(np.float32), 0)
    first = np.zeros((1, model.cfg.motion_dim), np.float32)
    sampler = CachedSampler(model)
    sampler.run(first, cond[:20], Sampling(0.3, rng))  # compile (numba caches it on disk)
    t = time.perf_counter()
    sampler.run(first, cond, Sampling(0.3, rng))
    cached = (frames - 1) / (time.perf_counter() - t)
    # Naive: time frames past the receptive field (full-length history), the steady state.
    n = rf + 150
    teacher = np.zeros((1, n, model.cfg.motion_dim), np.float32)
    t = time.perf_counter()
    naive_run(model, first, cond[:rf], teacher[:, :rf])
    warm = time.perf_counter() - t
    t = time.perf_counter()
    naive_run(model, first, cond[:n], teacher)
    naive = 150 / max(1e-9, time.perf_counter() - t - warm)
    return {"cached_fps": round(cached, 1), "naive_fps": round(naive, 1), "cached_over_naive": round(cached / naive, 1),
            "receptive_field_frames": rf}


def three_minute_song(weights: str | None, workdir: Path) -> dict:
    from dancenet_core.generate import generate_dance

    song = workdir / "three_minutes.wav"
    synth_song(song, 180.0)
    t = time.perf_counter()
    generate_dance(song, weights=weights, footfix=True)  # cold: analysis and first compile
    cold = time.perf_counter() - t
    t = time.perf_counter()
    result = generate_dance(song, weights=weights, footfix=True, seed=1)
    warm = time.perf_counter() - t
    return {"song_s": 180.0, "first_run_s_with_cold_analysis": round(cold, 2),
            "dance_s_with_cached_analysis": round(warm, 2),
            "stages_s": {k: round(v, 3) for k, v in result.timings.items()}}


def ten_minute_memory(weights: str | None, workdir: Path) -> dict:
    song = workdir / "ten_minutes.wav"
    synth_song(song, 600.0)
    code = (
        f"import resource, sys; sys.path.insert(0, {str(REPO)!r})\n"
        "from dancenet_core.generate import generate_dance\n"
        f"r = generate_dance({str(song)!r}, weights={weights!r})\n"
        "print(r.motions[0].num_frames, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    env_cache = {"DANCENET_CACHE": str(workdir / "cache")}
    import os

    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=os.environ | env_cache).stdout.split()
    return {"song_s": 600.0, "frames": int(out[0]), "peak_rss_mb": round(int(out[1]) / 1024, 1),
            "seconds": round(time.perf_counter() - t, 1)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--weights", default=None)
    p.add_argument("--skip-memory", action="store_true")
    args = p.parse_args()
    result: dict = {"sampler": sampler_speed(args.weights)}
    with tempfile.TemporaryDirectory() as d:
        result["three_minute_song"] = three_minute_song(args.weights, Path(d))
        if not args.skip_memory:
            result["ten_minute_song"] = ten_minute_memory(args.weights, Path(d))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
