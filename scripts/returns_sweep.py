"""What returns danced again cost, measured on the validation songs (training songs the models leave out, never the
test songs), as `dancenet evaluate` measures: both engines at their defaults (DanceNet locked to the beats with its
foot clean-up; the library engine on the users' library, the training dances but the validation ones, as BVH
without music) dance `--takes` takes of each song, and each row rewrites the same dances after they are danced, as
`evaluate` does:

- danced anew: the dances as they are;
- returns danced again: `repeats.dance_returns` (the default, `--returns repeat`);
- joins alone: every copy's joins and placement, its frames the same bars of another take of the same song (takes
  beyond the measured ones, never measured themselves);
- returns from another take: the copy as the default makes it (bar against bar, joins, placement, the real-time
  limit), its frames read from another take: everything a return does but repeat frames within the measured set;
- copied 2 bars off: each copy read from its own dance 2 bars later than its source (2 bars earlier where that would
  read what it writes): as much of the dance repeated, but not where the music returns.

Also prints each song's form (its sections and the bars the returns copy) and each row's figures per pair of takes
(the take-to-take spread; FIDs of a pair stand on a quarter of the segments, so they sit higher than the row's).
`--part test` measures the chosen settings once on the test songs (the training dances the library, the first two
rows only), as `dancenet evaluate` does.

    OMP_NUM_THREADS=1 python scripts/returns_sweep.py [--takes 4] [--part validation|test] [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

COLUMNS = ("fid_k", "fid_g", "div_k", "beat_align_score", "bas_own_ratio", "style_consistency", "foot_slide_ratio",
           "jitter_m_s2", "return_likeness")


def main() -> int:
    from dancenet_core.constants import DEFAULT_TEMPERATURE
    from dancenet_core.environment import default_data_dir
    from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features
    from dancenet_core.evaluation.form import song_forms
    from dancenet_core.evaluation.library_row import library_row, users_library
    from dancenet_core.evaluation.motion_style import MotionStyleModel
    from dancenet_core.evaluation.test_split import generate_for_pair, split_with_beats
    from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
    from dancenet_core.representation import decode
    from dancenet_core.shaping import repeats

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=4)
    parser.add_argument("--part", choices=("validation", "test"), default="validation")
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    data, fps, takes = args.data or default_data_dir(), 25.0, args.takes
    split, pairs, beats = split_with_beats(data, part=args.part)
    style_net = MotionStyleModel.load()
    bundle = DanceNetBundle.load(DEFAULT_BUNDLE)
    val = [pairs[s] for s in split[args.part] if pairs[s].style in style_net.styles]
    held = set(split["validation"]) if args.part == "validation" else set()
    train = [p for p in pairs.values() if p.seq in set(split["train"]) - held]
    lend = 2 if args.part == "validation" else 1  # takes danced per measured take: the others lend their frames
    reference = reference_features([decode(p.motion, fps, bundle.skeleton).positions() for p in train
                                    if p.style in style_net.styles], fps, style_net)
    forms = song_forms(val, data)
    for p in val:
        form, start = forms[p.seq]
        copies = repeats._copies(form, "repeat", {})
        end = start + len(p.motion) / fps  # the dance covers this span of the song; copies read and write within it
        danced = [(a, e) for a, e, s, _h in copies if form.bar_starts[s] >= start]
        print(json.dumps({"song": p.seq, "sections": " ".join(f"{s.name}:{s.bars}" for s in form.sections),
                          "bars": len(form.bar_starts) - 1, "copied_bars": int(sum(e - a for a, e, _s, _h in copies)),
                          "copies": len(copies), "danced_bars": int(np.sum((form.bar_starts[:-1] >= start)
                                                                           & (form.bar_starts[1:] <= end))),
                          "copied_danced_bars": int(sum(np.sum(form.bar_starts[a + 1:e + 1] <= end)
                                                        for a, e in danced))}), flush=True)
    # Takes 0..takes-1 are measured; take k + takes of the same song lends its frames to take k (validation).
    library = users_library(train, bundle.skeleton, fps)
    dances = {"DanceNet": [generate_for_pair(bundle, p, k, DEFAULT_TEMPERATURE, True, beats_s=beats[p.seq])[0]
                           for p in val for k in range(lend * takes)],
              "library": library_row(library, val, data, fps, lend * takes)[0]}
    songs = [p.seq for p in val for _ in range(takes)]
    styles = [p.style for p in val for _ in range(takes)]
    song_beats = [beats[p.seq] for p in val for _ in range(takes)]
    measured = [i * lend * takes + k for i in range(len(val)) for k in range(takes)]
    sample, bar_map, copies = repeats._sample, repeats._bar_map, repeats._copies

    def off(form, mode, section_modes):
        return [(a, e, s + 2 if s + 2 + e - a <= a else max(0, s - 2), h) for a, e, s, h in copies(form, mode,
                                                                                                    section_modes)]

    def rewritten(motion, donor, seq, how):
        if how == "anew":
            return motion
        form, start = forms[seq]
        try:
            if how == "copied 2 bars off":
                repeats._copies = off
            elif how != "repeat":
                repeats._sample = lambda _motion, frames: sample(donor, frames)
            if how == "joins alone":
                repeats._bar_map = lambda frames, _target, _source: frames
            return repeats.dance_returns(motion, form, start, "repeat")[0]
        finally:
            repeats._sample, repeats._bar_map, repeats._copies = sample, bar_map, copies

    out = {}
    for engine, made in dances.items():
        hows = ("anew", "repeat", "joins alone", "returns from another take", "copied 2 bars off")[:5 if lend == 2
                                                                                                     else 2]
        rows = [DanceSet(how, how, [rewritten(made[i], made[(i + takes) % len(made)], seq, how)
                                    for i, seq in zip(measured, songs, strict=True)], styles, song_beats, {}, songs)
                for how in hows]
        table = measure(rows, reference, fps, style_net, forms)
        pairs_of_takes = [[j for j in range(len(songs)) if j % takes // 2 == q] for q in range(takes // 2)]
        spread = [measure([r.only(q) for r in rows[:2]], reference, fps, style_net) for q in pairs_of_takes]
        for how, row in table.items():
            out[f"{engine}, {how}"] = {k: round(row[k], 4) for k in COLUMNS}
            if how in spread[0]:
                out[f"{engine}, {how}"]["per_pair_of_takes"] = {
                    k: [round(t[how][k], 4) for t in spread] for k in ("fid_k", "beat_align_score",
                                                                       "style_consistency")}
            print(f"{engine}, {how}", out[f"{engine}, {how}"], flush=True)
    print(json.dumps({"part": args.part, "songs": [p.seq for p in val], "takes": takes, "rows": out}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
