"""The foot step of generation, printed as JSON: seconds and peak traced memory for a 3-minute dance of the
shipped weights, for each foot clean-up (`engines.dancenet.clean_feet`: the contact lock, the Foot Constraint
Model, both, none; each with the floor pass) and the Foot Constraint Model's network alone (the whole step before
the contact lock and the floor pass), interleaved round by round in one run, with each one's ratio to that.

    .venv/bin/python bench/foot_cleanup.py [--rounds 5] [--seconds 180]

The dance is sampled from made-up music (random features), so the benchmark needs no data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core.engines.dancenet import CLEANUPS, clean_feet, finish_frames, foot_fixer, load_bundle  # noqa: E402
from dancenet_core.runtime.sampler import CachedSampler, Sampling, music_conditioning  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--seconds", type=float, default=180.0)
    args = p.parse_args()
    bundle = load_bundle()
    n = int(args.seconds * bundle.model.cfg.fps)
    music = np.random.default_rng(0).random((n, 15)).astype(np.float32)
    first = bundle.normalizer.normalize(bundle.start_frames[bundle.styles[0]][:1])
    frames, _ = CachedSampler(bundle.model).run(first, music_conditioning(bundle.model, music, 0),
                                                Sampling(1.0, np.random.default_rng(0)))
    feats = finish_frames(bundle, frames[0])
    fixer = foot_fixer()
    steps = {"foot model network alone": lambda: fixer(feats)}
    steps |= {f"clean_feet {c}": (lambda c=c: clean_feet(bundle, feats, c)) for c in (*CLEANUPS, None)}
    times: dict[str, list[float]] = {k: [] for k in steps}
    for _ in range(args.rounds):
        for name, step in steps.items():
            t = time.perf_counter()
            step()
            times[name].append(time.perf_counter() - t)
    base = float(np.median(times["foot model network alone"]))
    out: dict[str, dict] = {}
    for name, step in steps.items():
        tracemalloc.start()
        step()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        s = float(np.median(times[name]))
        out[name] = {"median_s": round(s, 4), "ratio": round(s / base, 2), "peak_traced_mib": round(peak, 1)}
    print(json.dumps({"dance_s": args.seconds, "rounds": args.rounds, "steps": out}, indent=1))


if __name__ == "__main__":
    main()
