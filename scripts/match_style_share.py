"""Share of a dance's frames from clips of the song's own style, the library's style labels hidden: the training
dances as a user's library (BVH, a folder per style, no music; built as `dancenet library build` builds one),
danced to the validation songs (the library without them: settings are chosen there) or to the test songs, with
the learned match of music and movement at each pair of weights given (its cosine per bar, its style term) and
without it (--match 0 with the style term 0: energy matching alone).

    .venv/bin/python scripts/match_style_share.py --songs validation --weights runs/match_validate.npz \
        --match 0 1 2 --match-style 0 10 20
    .venv/bin/python scripts/match_style_share.py --songs test --match 0 --match-style 20
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

from dancenet_core.data.build import MODEL_FPS, build_dataset, mean_skeleton
from dancenet_core.data.split import load_split
from dancenet_core.environment import default_data_dir
from dancenet_core.evaluation.library_row import users_library
from dancenet_core.evaluation.style_share import own_style_share
from dancenet_core.library.choreography import DEFAULT_SETTINGS
from dancenet_core.library.match import MATCH_WEIGHTS, MatchModel


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--songs", choices=("validation", "test"), default="validation")
    p.add_argument("--weights", default=str(MATCH_WEIGHTS))
    p.add_argument("--match", type=float, nargs="+", default=[0.0, DEFAULT_SETTINGS.match],
                   help="weights of the match's cost (0: without the match)")
    p.add_argument("--takes", type=int, default=1)
    p.add_argument("--match-style", type=float, nargs="+", default=[DEFAULT_SETTINGS.match_style],
                   help="weights of the match's style term (Settings.match_style), each tried with each --match")
    args = p.parse_args()
    data = default_data_dir()
    split = load_split()
    pairs = {q.seq: q for q in build_dataset(data, progress=False)}
    val = set(split["validation"])
    songs = split["validation"] if args.songs == "validation" else split["test"]
    library_seqs = [s for s in split["train"] if args.songs == "test" or s not in val]
    library = users_library([pairs[s] for s in library_seqs], mean_skeleton(list(pairs.values())), MODEL_FPS)
    model = MatchModel.load(args.weights)
    out = {"songs": args.songs, "library_clips": library.num_clips, "library_min": round(library.duration_s / 60, 1)}
    for w, ws in [(0.0, 0.0)] * (0.0 in args.match) + [(w, ws) for w in args.match for ws in args.match_style
                                                        if w > 0 or ws > 0]:
        t = time.perf_counter()
        r = own_style_share(library, [pairs[s] for s in songs], data, MODEL_FPS, args.takes,
                            model if w > 0 or ws > 0 else None,
                            dataclasses.replace(DEFAULT_SETTINGS, match=w, match_style=ws))
        r.update(match=w, match_style=ws, seconds=round(time.perf_counter() - t, 1))
        out[f"match_{w:g}_style_{ws:g}"] = r
        print(json.dumps({k: v for k, v in r.items() if k != "per_dance"}), flush=True)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
