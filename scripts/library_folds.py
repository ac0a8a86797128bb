"""The motion-library engine measured on every training song, held out by song: the training songs (the validation
songs among them) fall into `--folds` folds, and each fold's songs are danced from a library of the other folds'
dances (BVH in style folders, without music, as a user's) and measured against the other folds' real dances, as
`dancenet evaluate` measures the test songs. Eight times the validation songs' count, for choosing the library's
settings where five songs leave a choice to one song's luck; never the test songs.

Rows, the same dances rewritten after they are danced:
- danced anew: the dances as they are;
- returns danced again: `repeats.dance_returns` (the default, `--returns repeat`);
- joins alone: every copy's joins and placement, its frames the same bars of another take of the same song
  (takes never measured themselves): nothing copied from elsewhere in the song;
- returns from another take: the copies as the default makes them, their frames read from another take of the
  same song: everything a return does but repeat a stretch of its own dance.

`--set NAME=VALUE` dances with a plan setting of `library.choreography.Settings` changed (several may be given).
At 4 takes a mean over the folds moves by about 2 FID_k with the seeds (docs/experiments.md): compare settings
that differ by less than that with 8 takes or more, and again with other seeds (`--first-seed 8`).
Prints each fold's figures and their mean over the folds, with FID_k split into its two terms (the distance
between the means and the covariances' part), so a change shows whether it moves the dances' mean or their spread.

    OMP_NUM_THREADS=1 python scripts/library_folds.py [--takes 4] [--folds 5] [--set pile=0]
        [--first-seed 0] [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

COLUMNS = ("fid_k", "fid_g", "beat_align_score", "style_consistency", "return_likeness")
SEED = 0  # the songs' order before they are dealt into folds


def main() -> int:
    from dancenet_core.data.dance_with_melody import read_manifest
    from dancenet_core.environment import default_data_dir
    from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features, segments
    from dancenet_core.evaluation.dance_features import kinetic_features, smpl24_positions
    from dancenet_core.evaluation.form import song_forms
    from dancenet_core.evaluation.library_row import library_row, users_library
    from dancenet_core.evaluation.metrics import normalize_by
    from dancenet_core.evaluation.motion_style import MotionStyleModel
    from dancenet_core.evaluation.test_split import split_with_beats
    from dancenet_core.library.choreography import DEFAULT_SETTINGS
    from dancenet_core.music.features import analyze_music
    from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
    from dancenet_core.representation import decode
    from dancenet_core.shaping import repeats

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=4)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--first-seed", type=int, default=0, help="take k is danced with seed FIRST_SEED + k")
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    names = {f.name for f in dataclasses.fields(DEFAULT_SETTINGS)}
    try:
        changed = {k: float(v) for k, v in (item.split("=", 1) for item in args.set)}
    except ValueError:
        parser.error("--set takes NAME=NUMBER, e.g. --set cut=0.1")
    if set(changed) - names:
        parser.error(f"--set: no plan setting {sorted(set(changed) - names)}; the settings: {', '.join(sorted(names))}")
    settings = dataclasses.replace(DEFAULT_SETTINGS, **changed)
    data, fps, takes = args.data or default_data_dir(), 25.0, args.takes
    split, pairs, _beats = split_with_beats(data, part="validation")
    style_net = MotionStyleModel.load()
    skeleton = DanceNetBundle.load(DEFAULT_BUNDLE).skeleton
    songs = [s for s in split["train"] if pairs[s].style in style_net.styles]
    order = list(np.random.default_rng(SEED).permutation(sorted(songs)))
    folds = [order[f::args.folds] for f in range(args.folds)]
    seqs = {s.seq: s for s in read_manifest(data)}
    beats = {s: analyze_music(seqs[s].audio).beat_times - seqs[s].music_offset_s for s in songs}
    forms = song_forms([pairs[s] for s in songs], data)
    real = {s: decode(pairs[s].motion, fps, skeleton).positions() for s in songs}
    sample, bar_map = repeats._sample, repeats._bar_map

    def rewritten(motion, donor, seq: str, how: str):
        if how == "anew":
            return motion
        try:
            if how != "repeat":
                repeats._sample = lambda _motion, frames: sample(donor, frames)
            if how == "joins alone":
                repeats._bar_map = lambda frames, _target, _source: frames
            return repeats.dance_returns(motion, *forms[seq], "repeat")[0]
        finally:
            repeats._sample, repeats._bar_map = sample, bar_map

    hows = ("anew", "repeat", "joins alone", "returns from another take")
    per_fold: dict[str, list[dict]] = {how: [] for how in hows}
    for f, fold in enumerate(folds):
        rest = [s for s in songs if s not in fold]
        reference = reference_features([real[s] for s in rest], fps, style_net)
        library = users_library([pairs[s] for s in rest], skeleton, fps)
        made = library_row(library, [pairs[s] for s in fold], data, fps, 2 * takes,  # take k + takes lends
                           settings=settings, first_seed=args.first_seed)[0]
        measured = [(i * 2 * takes + k, seq) for i, seq in enumerate(fold) for k in range(takes)]
        rows = [DanceSet(how, how, [rewritten(made[j], made[j + takes], seq, how) for j, seq in measured],
                         [pairs[seq].style for _j, seq in measured], [beats[seq] for _j, seq in measured], {},
                         [seq for _j, seq in measured]) for how in hows]
        table = measure(rows, reference, fps, style_net, forms)
        for row in rows:
            # kinetic features alone (`measure` computed them with the style net's, and returns neither)
            gen = np.stack([kinetic_features(smpl24_positions(seg), fps) for m in row.dances
                            for seg in segments(m.positions(), fps)])
            keep = reference["k"].std(axis=0) > 1e-6
            r, g = (normalize_by(reference["k"][:, keep], x[:, keep]) for x in (reference["k"], gen))
            mean_term = float(((r.mean(axis=0) - g.mean(axis=0)) ** 2).sum())
            figures = {k: table[row.name][k] for k in COLUMNS} | {"fid_k_mean_term": mean_term}
            per_fold[row.name].append(figures)
            print(json.dumps({"fold": f, "songs": fold, "row": row.name}
                             | {k: round(v, 4) for k, v in figures.items() if v is not None}), flush=True)
    summary = {how: {k: round(float(np.mean([d[k] for d in rows if d[k] is not None])), 4)
                     for k in (*COLUMNS, "fid_k_mean_term") if any(d[k] is not None for d in rows)}
               | {"fid_k_per_fold": [round(d["fid_k"], 2) for d in rows]} for how, rows in per_fold.items()}
    print(json.dumps({"folds": folds, "takes": takes, "settings": changed, "mean_over_folds": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
