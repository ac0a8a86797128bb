"""The song's form and returns danced again, on songs whose form is known: each arranged A B A C A B from the
8 bars after the 4th downbeat of three training songs of one style, cut on their downbeats
(`evaluation.form.arranged_song`). Prints JSON: per song, the form read and whether it is right, its time once
the features are cached, and per engine and returns mode the return likeness (the pose distance between
occurrences of a section over that between different sections: 0 danced exactly again, about 1 danced no more
alike than different sections) and the seconds the returns took.

    python bench/form.py [--data ../shared/data] [--engines dancenet library]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

# the songs of A, B and C
ARRANGEMENTS = (("DANCE_W_1", "DANCE_W_2", "DANCE_W_4"), ("DANCE_C_6", "DANCE_C_7", "DANCE_C_8"),
                ("DANCE_R_2", "DANCE_R_3", "DANCE_R_8"), ("DANCE_W_9", "DANCE_W_11", "DANCE_W_14"))


def main() -> int:
    from dancenet_core.evaluation.form import arranged_song, return_likeness
    from dancenet_core.generate import generate_dance
    from dancenet_core.music.features import analyze_music
    from dancenet_core.music.form import song_form
    from dancenet_core.representation import heading_frames
    from dancenet_core.request import DanceRequest

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--engines", nargs="+", default=["dancenet", "library"])
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for songs in ARRANGEMENTS:
            name = "+".join(songs)
            song = arranged_song(args.data, Path(tmp) / f"{name}.wav", songs=songs)
            if song is None:
                print(f"the Dance with Melody songs are not in {args.data}: give --data", file=sys.stderr)
                return 1
            analysis = analyze_music(song)
            t = time.perf_counter()
            form = song_form(analysis)
            row = {"song": name, "form": form.labels, "right": form.labels == "ABACAB",
                   "even": len({s.bars for s in form.sections}) == 1,
                   "bars": [s.bars for s in form.sections], "form_ms": round(1000 * (time.perf_counter() - t), 2)}
            for engine in args.engines:
                for mode in ("anew", "repeat"):
                    r = generate_dance(DanceRequest(song, engine=engine, returns=mode, seed=1))
                    m = r.motions[0]
                    like = return_likeness(m.positions(), heading_frames(m), m.fps, r.form, r.start_s)
                    row[f"{engine}_{mode}"] = None if like is None else round(like, 3)
                    row[f"{engine}_{mode}_returns_s"] = round(r.timings.get("returns_s", 0.0), 3)
            rows.append(row)
    print(json.dumps({"songs": rows, "labels_right": sum(r["right"] for r in rows),
                      "sections_even": sum(r["even"] for r in rows), "of": len(rows)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
