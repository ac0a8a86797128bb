"""The settings of DanceNet's clean-up after sampling, on the validation songs: the foot clean-up's hold thresholds
(a toe end within GROUND_M of the floor and slower than STILL_MPS stands, whatever the model predicted:
`footlock.planted_feet`) and the beat lock's largest warp and reach (`beatlock.beat_warp`; warp 0: no lock). Each
GROUND_M:STILL_MPS:WARP:REACH setting given dances the validation songs as `dancenet validate` does (the shipped
weights, temperature 1, output smoothing 1.5, the contact lock) and is measured against the real validation dances;
the table is printed as markdown.

    .venv/bin/python scripts/cleanup_sweep.py [--takes 4] 0.02:0.5:0:0 0.05:0.65:0.15:0.5 ...

Why: the sliding measure counts a toe within 5 cm of the floor moving faster than 0.25 m/s, and a foot the model
swings low and slowly slides there unless the clean-up holds it; the beat lock trades how many of the dance's
beats it can move onto the song's against how far from its own speed it plays the dance.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.evaluation import test_split  # noqa: E402
from dancenet_core.evaluation.comparison import DanceSet, dance_row, markdown, measure, reference_features  # noqa: E402
from dancenet_core.evaluation.motion_style import MotionStyleModel  # noqa: E402
from dancenet_core.evaluation.test_split import split_with_beats  # noqa: E402
from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle  # noqa: E402
from dancenet_core.representation import decode  # noqa: E402
from dancenet_core.shaping import footlock  # noqa: E402
from dancenet_core.shaping.beatlock import lock_to_beats  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("settings", nargs="+", help="GROUND_M:STILL_MPS:WARP:REACH (metres, metres per second, share of "
                   "the speed, share of the beat interval)")
    p.add_argument("--takes", type=int, default=4)
    args = p.parse_args()
    split, pairs, beats = split_with_beats(default_data_dir(), part="validation")
    style_net = MotionStyleModel.load()
    bundle = DanceNetBundle.load(DEFAULT_BUNDLE)
    fps = bundle.model.cfg.fps
    val = [pairs[s] for s in split["validation"]]
    trained_on = set(split["train"]) - set(split["validation"])
    ref = reference_features([decode(p.motion, fps, bundle.skeleton).positions()
                              for p in pairs.values() if p.seq in trained_on], fps, style_net)
    rows = [DanceSet("real", "Real dances (validation songs)", [decode(p.motion, fps, bundle.skeleton) for p in val],
                     [p.style for p in val], [beats[p.seq] for p in val])]
    for setting in args.settings:
        footlock.GROUND_M, footlock.STILL_MPS, warp, reach = (float(x) for x in setting.split(":"))
        test_split.lock_beats = lambda b, f, s, keep=0, w=warp, r=reach: lock_to_beats(
            f, b.model.cfg.fps, b.skeleton, s, keep, w, r)[0]
        label = (f"hold within {footlock.GROUND_M * 100:g} cm, under {footlock.STILL_MPS:g} m/s; "
                 + (f"beat lock: warp {warp:g}, reach {reach:g} beat" if warp else "no beat lock"))
        rows.append(dance_row(setting, label, bundle, val, beats, args.takes, 1.0, footfix=True, beat_lock=warp > 0))
        print(f"  {setting}: {len(rows[-1].dances)} dances", file=sys.stderr, flush=True)
    md = markdown(measure(rows, ref, fps, style_net), 0.0, 0, args.takes, len(ref["hit"]))
    print(md.split("\nLower is better")[0] + f"\n{args.takes} takes per validation song "
          f"({', '.join(split['validation'])}), against the {len(ref['hit'])} 10-s segments of the dances the model "
          "trained on.")


if __name__ == "__main__":
    main()
