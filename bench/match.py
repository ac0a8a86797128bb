"""The learned match's cost in the library plan: the first 3 minutes of a test song (DANCE_C_2's, analysed once,
from the shared data) danced from the shipped CMU library without the match; with it on the same clips built as a
library whose clips name no style (the libraries the match dances), just loaded from its file ("first": the match's
motion features stored by the build), the same with those features computed at the dance ("computed": a library
built before they were stored, a forward kinematics pass over the whole library), and with it again on a loaded
library (the features kept). Each the best of `REPEATS`, interleaved, in one process (the loads not timed); prints
JSON with the ratios to the dance without the match and each dance's cuts (the render's work grows with them).

    OMP_NUM_THREADS=1 .venv/bin/python bench/match.py
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
from pathlib import Path

from dancenet_core.data.dance_with_melody import read_manifest
from dancenet_core.environment import default_data_dir
from dancenet_core.library.choreography import choreograph
from dancenet_core.library.match import MatchModel, frames_of
from dancenet_core.library.store import MotionLibrary, load_default
from dancenet_core.music.features import analyze_music

SONG = "DANCE_C_2"
SONG_S = 180.0
REPEATS = 5


def main() -> None:
    library, model = load_default(), MatchModel.load()
    song = next(r for r in read_manifest(default_data_dir()) if r.seq == SONG)
    music = analyze_music(song.audio)
    times: dict[str, list[float]] = {"without": [], "first": [], "computed": [], "again": []}
    cuts = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "unsorted.npz"
        unsorted = dataclasses.replace(library, styles=[""] * library.num_clips)
        frames_of(unsorted)  # as `dancenet library build` does for a library whose clips name no style
        unsorted.save(path)
        kept = MotionLibrary.load(path)
        for _ in range(REPEATS):
            for what in times:
                lib = {"without": library, "again": kept}.get(what) or MotionLibrary.load(path)
                if what == "computed":
                    lib.match_frames = None
                t = time.perf_counter()
                dance = choreograph(lib, music, seed=0, end_s=SONG_S, match=None if what == "without" else model)[0]
                times[what].append(time.perf_counter() - t)
                cuts[what] = len(dance.report.cuts)
    best = {k: min(v) for k, v in times.items()}
    print(json.dumps({"library_min": round(library.duration_s / 60, 1), "song": SONG, "song_s": SONG_S,
                      "cuts_without": cuts["without"], "cuts_with": cuts["again"],
                      **{f"dance_{k}_s": round(v, 3) for k, v in best.items()},
                      "ratio_first": round(best["first"] / best["without"], 2),
                      "ratio_computed": round(best["computed"] / best["without"], 2),
                      "ratio_again": round(best["again"] / best["without"], 2)}, indent=1))


if __name__ == "__main__":
    main()
