"""The library plan's use of the song's form, measured on the validation songs (training songs the models leave
out, never the test songs): cuts kept to phrase starts (`Settings.off_phrase`) and a bar's energy drawn toward its
section's (`Settings.section_energy`), each against the plan without them, as `dancenet evaluate` measures (the
users' library: the training dances but the validation ones, as BVH without music).

    python scripts/library_form_sweep.py [--takes 6] [--data ../shared/data]
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
           "section energy": {"section_energy": 0.5}, "both": {"off_phrase": 1.0, "section_energy": 0.5}}


def main() -> int:
    from dancenet_core.environment import default_data_dir
    from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features
    from dancenet_core.evaluation.library_row import library_row, users_library
    from dancenet_core.evaluation.motion_style import MotionStyleModel
    from dancenet_core.evaluation.test_split import split_with_beats
    from dancenet_core.library.choreography import DEFAULT_SETTINGS
    from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
    from dancenet_core.representation import decode

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", type=int, default=6)
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    data, fps = args.data or default_data_dir(), 25.0
    split, pairs, _beats = split_with_beats(data, part="validation")
    style_net = MotionStyleModel.load()
    skeleton = DanceNetBundle.load(DEFAULT_BUNDLE).skeleton
    held = set(split["validation"])
    val = [pairs[s] for s in split["validation"] if pairs[s].style in style_net.styles]
    train = [p for p in pairs.values() if p.seq in set(split["train"]) - held]
    reference = reference_features([decode(p.motion, fps, skeleton).positions() for p in train
                                    if p.style in style_net.styles], fps, style_net)
    library = users_library(train, skeleton, fps)
    out = {}
    for name, changes in CONFIGS.items():
        dances, styles, beats, _info = library_row(library, val, data, fps, args.takes,
                                                   settings=dataclasses.replace(DEFAULT_SETTINGS, **changes))
        row = measure([DanceSet(name, name, dances, styles, beats)], reference, fps, style_net)[name]
        out[name] = {k: round(row[k], 3) for k in ("fid_k", "fid_g", "div_k", "beat_align_score", "bas_own_ratio",
                                                   "style_consistency", "joint_speed_m_s")}
        print(name, out[name], flush=True)
    print(json.dumps({"validation_songs": [p.seq for p in val], "takes": args.takes, "rows": out}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
