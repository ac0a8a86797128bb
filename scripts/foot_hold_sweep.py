"""The foot clean-up's hold thresholds on the validation songs: a toe end within GROUND_M of the floor and slower than
STILL_MPS stands, whatever the model predicted (`footlock.planted_feet`). Each GROUND_M:STILL_MPS pair given dances
the validation songs as `dancenet validate` does (the shipped weights, temperature 1, output smoothing 1.5, beat lock
and contact lock on) and is measured against the real validation dances; the table is printed as markdown.

    .venv/bin/python scripts/foot_hold_sweep.py [--takes 4] 0.02:0.5 0.05:0.65 ...

Why: the sliding measure counts a toe within 5 cm of the floor moving faster than 0.25 m/s; a foot the model swings
low and slowly slides there unless the clean-up holds it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dancenet_core import footlock  # noqa: E402
from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.evaluation.comparison import DanceSet, dance_row, markdown, measure, reference_features  # noqa: E402
from dancenet_core.evaluation.motion_style import MotionStyleModel  # noqa: E402
from dancenet_core.evaluation.test_split import split_with_beats  # noqa: E402
from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle  # noqa: E402
from dancenet_core.representation import decode  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("holds", nargs="+", help="GROUND_M:STILL_MPS pairs (metres, metres per second)")
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
    for hold in args.holds:
        footlock.GROUND_M, footlock.STILL_MPS = (float(x) for x in hold.split(":"))
        rows.append(dance_row(hold, f"within {footlock.GROUND_M * 100:g} cm, under {footlock.STILL_MPS:g} m/s",
                              bundle, val, beats, args.takes, 1.0, footfix=True, beat_lock=True))
        print(f"  {hold}: {len(rows[-1].dances)} dances", file=sys.stderr, flush=True)
    md = markdown(measure(rows, ref, fps, style_net), 0.0, 0, args.takes, len(ref["hit"]))
    print(md.split("\nLower is better")[0] + f"\n{args.takes} takes per validation song "
          f"({', '.join(split['validation'])}), against the {len(ref['hit'])} 10-s segments of the dances the model "
          "trained on.")


if __name__ == "__main__":
    main()
