"""The learned match's cost in the library plan: the first 3 minutes of a test song (DANCE_C_2's, analysed once,
from the shared data) danced from the shipped CMU library without the match, with it on a library seen for the first
time (the forward kinematics of the whole library included) and with it again (the library's motion features kept).
Each the best of `REPEATS`, interleaved, in one process; prints JSON with the ratios to the dance without the match
and each dance's cuts (the render's work grows with them).

    OMP_NUM_THREADS=1 .venv/bin/python bench/match.py
"""

from __future__ import annotations

import json
import time

from dancenet_core.data.dance_with_melody import read_manifest
from dancenet_core.environment import default_data_dir
from dancenet_core.library import match as match_module
from dancenet_core.library.choreography import choreograph
from dancenet_core.library.match import MatchModel
from dancenet_core.library.store import load_default
from dancenet_core.music.features import analyze_music

SONG = "DANCE_C_2"
SONG_S = 180.0
REPEATS = 5


def main() -> None:
    library, model = load_default(), MatchModel.load()
    song = next(r for r in read_manifest(default_data_dir()) if r.seq == SONG)
    music = analyze_music(song.audio)
    times: dict[str, list[float]] = {"without": [], "first": [], "again": []}
    cuts = {}
    for _ in range(REPEATS):
        for what in times:
            if what == "first":
                match_module._FRAMES.clear()
            t = time.perf_counter()
            dance = choreograph(library, music, seed=0, end_s=SONG_S, match=None if what == "without" else model)[0]
            times[what].append(time.perf_counter() - t)
            cuts[what] = len(dance.report.cuts)
    best = {k: min(v) for k, v in times.items()}
    print(json.dumps({"library_min": round(library.duration_s / 60, 1), "song": SONG, "song_s": SONG_S,
                      "cuts_without": cuts["without"], "cuts_with": cuts["again"],
                      **{f"dance_{k}_s": round(v, 3) for k, v in best.items()},
                      "ratio_first": round(best["first"] / best["without"], 2),
                      "ratio_again": round(best["again"] / best["without"], 2)}, indent=1))


if __name__ == "__main__":
    main()
