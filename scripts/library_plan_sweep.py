"""The library plan's settings, measured as `dancenet evaluate` measures (the users' library: the training dances but
the measured ones, as BVH without music), each danced anew and with the song's returns danced again (the default,
`shaping.repeats.dance_returns`), the same dances rewritten: FID_k, FID_g, Beat Align Score, style consistency, return
likeness and the plan's cuts. Settings are chosen on the validation songs (training songs the models leave out);
`--part test` measures chosen settings once on the test songs, against the shipped plan in the same run.

- cuts on phrase starts (`Settings.off_phrase`) and a bar's energy drawn toward its section's
  (`Settings.section_energy`): the plan's use of the song's form;
- the cost of a cut over carrying on with the clip (`Settings.cut`), alone and with a lighter energy match.

    OMP_NUM_THREADS=1 python scripts/library_plan_sweep.py [--takes 16] [--part validation|test]
        [--configs NAME ...] [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CONFIGS = {"plan as shipped": {}, "cuts on phrase starts": {"off_phrase": 1.0},
           "section energy": {"section_energy": 0.5}, "both": {"off_phrase": 1.0, "section_energy": 0.5},
           "cut 0.1": {"cut": 0.1}, "cut 0.05": {"cut": 0.05},
           "cut 0.05, energy 1": {"cut": 0.05, "energy": 1.0}}
COLUMNS = ("fid_k", "fid_g", "div_k", "beat_align_score", "bas_own_ratio", "style_consistency", "joint_speed_m_s",
           "return_likeness")
PLAN = ("cuts", "long_run_share", "cuts_over", "transition_frames_over_p99", "max_warp")


def main() -> int:
    from dancenet_core.environment import default_data_dir
    from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features
    from dancenet_core.evaluation.form import danced_again, song_forms
    from dancenet_core.evaluation.library_row import library_row, users_library
    from dancenet_core.evaluation.motion_style import MotionStyleModel
    from dancenet_core.evaluation.test_split import split_with_beats
    from dancenet_core.library.choreography import DEFAULT_SETTINGS
    from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
    from dancenet_core.representation import decode

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=16)
    parser.add_argument("--part", choices=("validation", "test"), default="validation")
    parser.add_argument("--configs", nargs="+", choices=sorted(CONFIGS), default=list(CONFIGS))
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    data, fps = args.data or default_data_dir(), 25.0
    split, pairs, _beats = split_with_beats(data, part=args.part)
    style_net = MotionStyleModel.load()
    skeleton = DanceNetBundle.load(DEFAULT_BUNDLE).skeleton
    held = set(split["validation"]) if args.part == "validation" else set()
    measured = [pairs[s] for s in split[args.part] if pairs[s].style in style_net.styles]
    train = [p for p in pairs.values() if p.seq in set(split["train"]) - held]
    reference = reference_features([decode(p.motion, fps, skeleton).positions() for p in train
                                    if p.style in style_net.styles], fps, style_net)
    library = users_library(train, skeleton, fps)
    forms = song_forms(measured, data)
    songs = [p.seq for p in measured for _ in range(args.takes)]
    out = {}
    for name in args.configs:
        settings = dataclasses.replace(DEFAULT_SETTINGS, **CONFIGS[name])
        dances, styles, beats, info = library_row(library, measured, data, fps, args.takes, settings=settings)
        rows = [DanceSet(f"{name}, anew", name, dances, styles, beats, {}, songs),
                DanceSet(f"{name}, returns", name, danced_again(dances, songs, forms), styles, beats, {}, songs)]
        for row_name, row in measure(rows, reference, fps, style_net, forms).items():
            out[row_name] = {k: round(row[k], 4) for k in COLUMNS} | {k: round(info[k], 4) for k in PLAN}
            print(row_name, out[row_name], flush=True)
    print(json.dumps({"part": args.part, "songs": [p.seq for p in measured], "takes": args.takes, "rows": out},
                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
