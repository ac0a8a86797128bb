"""Motion library engine: `library build` of 30 minutes of clips, and a 3-minute song's dance from it.

The clips are the Dance with Melody training dances (as the evaluation decodes them) written as BVH files of our 55
joints into a temporary folder, up to 30 minutes; the song is a 3-minute beat grid at 120 BPM in 4/4 with onsets
on the beats. Prints JSON: build seconds (cold, then from the cache), the dance's seconds (the first, then the best
of 3 alternating with the plan's cost on piled extremes off, `Settings.pile`, and their ratio), and the process's
high-water mark of memory (VmHWM) after each step.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

LIBRARY_MIN = 30.0
SONG_S = 180.0


def vm_hwm_mb() -> float:
    with open("/proc/self/status") as f:
        line = next(line for line in f if line.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        from dancenet_core.bvh import write_bvh
        from dancenet_core.data.build import build_dataset
        from dancenet_core.data.split import load_split
        from dancenet_core.environment import default_data_dir
        from dancenet_core.library.build import build_library
        from dancenet_core.library.choreography import DEFAULT_SETTINGS, choreograph
        from dancenet_core.music.features import N_FEATURES, ONSET_COL, MusicAnalysis
        from dancenet_core.representation import decode
        from dancenet_core.skeleton import DEFAULT_SKELETON

        folder = Path(tmp) / "clips"
        train = set(load_split()["train"])
        minutes = 0.0
        for p in build_dataset(default_data_dir(), progress=False):
            if p.seq not in train or minutes >= LIBRARY_MIN:
                continue
            motion = decode(p.motion, 25.0, DEFAULT_SKELETON)
            motion = motion[: int(min(motion.num_frames, (LIBRARY_MIN - minutes) * 60 * 25))]
            if motion.duration < 10:
                break
            (folder / p.style).mkdir(parents=True, exist_ok=True)
            write_bvh(folder / p.style / f"{p.seq}.bvh", motion)
            minutes += motion.duration / 60
        os.environ["DANCENET_CACHE"] = str(Path(tmp) / "cache")  # a cold library build (the dataset's cache kept)
        hwm_before = vm_hwm_mb()
        t = time.perf_counter()
        library, _ = build_library(folder, report=lambda _line: None)
        build_s = time.perf_counter() - t
        hwm_build = vm_hwm_mb()
        t = time.perf_counter()
        build_library(folder, report=lambda _line: None)
        cached_s = time.perf_counter() - t

        beats = np.arange(0.25, SONG_S, 0.5)
        feats = np.zeros((int(SONG_S * 10), N_FEATURES), np.float32)
        feats[(beats * 10).astype(int), ONSET_COL] = 1.0 + (np.arange(len(beats)) // 32 % 2)
        music = MusicAnalysis(feats, beats, beats[::4], 120.0, SONG_S)
        t = time.perf_counter()
        dance = choreograph(library, music, seed=0)[0]
        dance_s = time.perf_counter() - t
        best = {"default": np.inf, "no_pile": np.inf}
        for _ in range(3):
            for name, settings in (("default", DEFAULT_SETTINGS), ("no_pile", replace(DEFAULT_SETTINGS, pile=0.0))):
                t = time.perf_counter()
                choreograph(library, music, seed=0, settings=settings)
                best[name] = min(best[name], time.perf_counter() - t)
        print(json.dumps({
            "library_min": round(library.duration_s / 60, 2), "clips": library.num_clips,
            "bvh_mb": round(sum(f.stat().st_size for f in folder.rglob("*.bvh")) / 2**20, 1),
            "build_s": round(build_s, 2), "build_cached_s": round(cached_s, 3),
            "song_s": SONG_S, "dance_s": round(dance_s, 3),
            "dance_again_s": round(best["default"], 3), "dance_again_no_pile_s": round(best["no_pile"], 3),
            "pile_cost_ratio": round(best["default"] / best["no_pile"], 3), "dance_frames": dance.motion.num_frames,
            "figures": len(dance.report.figures), "cuts": len(dance.report.cuts),
            "vm_hwm_mb_before_build": round(hwm_before), "vm_hwm_mb_after_build": round(hwm_build),
            "vm_hwm_mb_after_dance": round(vm_hwm_mb()),
        }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
