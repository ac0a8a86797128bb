"""A folder of dance clips in every skeleton convention the library reads, made from the CMU dance capture: the
"done when" folder of issue 45's source conventions, for `dancenet library build OUT_DIR`.

Each clip is a span (1-60 s) of a CMU dance trial ($DANCENET_DATA/cmu_dance, its walk left out) read onto our
skeleton and written as BVH by the conventions' retargeting of tests/conventions.py (Mixamo with and without its
prefix and fingers, VRM, Unreal, Character Creator with a T-pose first frame, Rokoko, DAZ, MMD, Rigify, the metarig,
generic names, CMU, ours; cm, mm, inches; Z up; A-poses; 24-120 fps), in one flat folder without labels. Prints
one line per clip: its file, convention, length, and the bone map Auto finds for it.

    .venv/bin/python scripts/convention_clips.py OUT_DIR [--count 40] [--seed 0]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from conventions import CONVENTIONS, convention_bvh  # noqa: E402 (tests/conventions.py)

from dancenet_core.bvh import write_bvh_data  # noqa: E402
from dancenet_core.environment import default_data_dir  # noqa: E402
from dancenet_core.jointmap import armature_pose, rotation_motion  # noqa: E402
from dancenet_core.library.bvhclip import bvh_rig  # noqa: E402

LEFT_OUT = {"05/05_01_poses.bvh"}  # a walk
SPAN_S = (1.2, 60.0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="folder to write the clips into (made if missing)")
    parser.add_argument("--count", type=int, default=40, help="clips to write (default 40)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--source", type=Path, default=default_data_dir() / "cmu_dance", help="the CMU dance folder")
    args = parser.parse_args(argv)
    with open(args.source / "manifest.csv", newline="") as f:
        trials = [r["file"] for r in csv.DictReader(f) if r["file"] not in LEFT_OUT]
    rng = np.random.default_rng(args.seed)
    names = list(CONVENTIONS)
    args.out.mkdir(parents=True, exist_ok=True)
    for i in range(args.count):
        trial = args.source / trials[rng.integers(len(trials))]
        rig = bvh_rig(trial)
        motion = rotation_motion(armature_pose(rig.joints, rig.rest, rig.pose, rig.fps, trial.name))
        seconds = min(rng.uniform(*SPAN_S), motion.duration)
        start = int(rng.uniform(0, motion.duration - seconds) * motion.fps)
        span = motion[start : start + round(seconds * motion.fps)]
        convention = names[i % len(names)]
        path = args.out / f"{i:02d}_{trial.stem.removesuffix('_poses')}_{convention}.bvh"
        write_bvh_data(path, convention_bvh(span, CONVENTIONS[convention]))
        print(f"{path.name:40s} {convention:18s} {span.duration:5.1f} s  Auto: {bvh_rig(path).convention}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
