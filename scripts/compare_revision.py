"""Both engines of another revision against this checkout's, on the test songs, as a user runs them, measured in one
run: whether a change left the dances no worse than before it.

Each revision (a `git worktree` of REV, and this checkout) dances every test song's span in a process of its own,
through its own `generate_dance` at its defaults: the song's style asked for, takes with seeds 0, 1, ..., DanceNet
and the motion-library engine, the library built from the training dances as a user's folder holds clips (BVH
files, a folder per style, no music) by the revision's own `build_library` first. The dances come back as arrays
and are measured here with this checkout's `dancenet evaluate` code against the same real dances: every row of all
takes, and each pair of takes alone (the take-to-take spread). Only `DanceRequest`, `generate_dance` and
`build_library` are asked of REV, so any revision that has them can be compared.

    python scripts/compare_revision.py REV [--takes 8] [--engines dancenet library] [--out DIR] [--data DIR]

Writes `comparison_<REV>.json` in `--out` (default out/compare_revision), with each side's dances
(`<engine>_rev.npz`, `<engine>_this.npz`: `dance`'s arrays), and prints each row's columns.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
COLUMNS = ("fid_k", "fid_g", "beat_align_score", "style_consistency", "return_likeness", "joint_speed_m_s")


def dance(jobs: Path, out: Path) -> None:
    """The dancing side, run with PYTHONPATH at a revision: every job of `jobs` (JSON) danced by that revision's
    `generate_dance`, its motions saved in `out` (npz: each dance's rotations and root positions, at the jobs' fps)."""
    import dancenet_core
    from dancenet_core.generate import generate_dance
    from dancenet_core.request import DanceRequest

    print(f"  dancing with {Path(dancenet_core.__file__).parent}", flush=True)
    spec = json.loads(jobs.read_text())
    if any(job["engine"] == "library" for job in spec["jobs"]):  # as `dancenet library build` does first
        from dancenet_core.library.build import build_library
        build_library(spec["library"], report=lambda _line: None)
    arrays: dict[str, np.ndarray] = {}
    for i, job in enumerate(spec["jobs"]):
        library = Path(spec["library"]) if job["engine"] == "library" else None
        m = generate_dance(DanceRequest(Path(job["song"]), style=job["style"], seed=job["seed"],
                                        start_s=job["start_s"], end_s=job["end_s"], fps=spec["fps"],
                                        engine=job["engine"], library=library)).motions[0]
        arrays[f"rot{i}"], arrays[f"root{i}"] = m.rotations, m.root_positions
    np.savez(out, **arrays)


def main() -> int:
    sys.path[:0] = [str(ROOT), str(ROOT / "bench")]
    from revision import worktree

    from dancenet_core.atomic import write_text
    from dancenet_core.bvh import write_bvh
    from dancenet_core.data.dance_with_melody import read_manifest
    from dancenet_core.environment import default_data_dir
    from dancenet_core.evaluation.comparison import DanceSet, measure, reference_features
    from dancenet_core.evaluation.form import song_forms
    from dancenet_core.evaluation.motion_style import MotionStyleModel
    from dancenet_core.evaluation.test_split import split_with_beats
    from dancenet_core.motion import Motion
    from dancenet_core.nets.bundle import DEFAULT_BUNDLE, DanceNetBundle
    from dancenet_core.representation import decode

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rev", help="the revision to compare with this checkout (a commit, tag or branch)")
    parser.add_argument("--takes", type=int, default=8)
    parser.add_argument("--engines", nargs="+", default=["dancenet", "library"], choices=["dancenet", "library"])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "compare_revision")
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    if args.takes < 2 or args.takes % 2:
        parser.error("--takes must be even (the spread is measured on pairs of takes)")
    # the revision first: one that the repository lacks is said before the data are read
    with worktree(args.rev) as (commit, tree), tempfile.TemporaryDirectory() as tmp:
        data, fps = args.data or default_data_dir(), 25.0
        split, pairs, beats = split_with_beats(data)
        style_net = MotionStyleModel.load()
        skeleton = DanceNetBundle.load(DEFAULT_BUNDLE).skeleton
        test = [pairs[s] for s in split["test"] if pairs[s].style in style_net.styles]
        train = [(p, decode(p.motion, fps, skeleton)) for p in pairs.values() if p.seq in set(split["train"])]
        seqs = {s.seq: s for s in read_manifest(data)}
        rows = [DanceSet("real", "real dances", [decode(p.motion, fps, skeleton) for p in test],
                         [p.style for p in test], [beats[p.seq] for p in test], {}, [p.seq for p in test])]
        songs = [p.seq for p in test for _ in range(args.takes)]
        styles = [p.style for p in test for _ in range(args.takes)]
        song_beats = [beats[p.seq] for p in test for _ in range(args.takes)]
        folder = Path(tmp) / "library"
        for p, motion in train:
            (folder / p.style).mkdir(parents=True, exist_ok=True)
            write_bvh(folder / p.style / f"{p.seq}.bvh", motion)
        jobs = Path(tmp) / "jobs.json"
        for engine in args.engines:
            jobs.write_text(json.dumps({"library": str(folder), "fps": fps, "jobs": [
                {"engine": engine, "song": str(seqs[p.seq].audio), "style": p.style, "seed": k,
                 "start_s": seqs[p.seq].music_offset_s, "end_s": seqs[p.seq].music_offset_s + len(p.motion) / fps}
                for p in test for k in range(args.takes)]}))
            for name, root, tag in ((args.rev, tree, "rev"), ("this checkout", ROOT, "this")):
                args.out.mkdir(parents=True, exist_ok=True)
                saved = args.out / f"{engine}_{tag}.npz"
                print(f"{engine}: {name} dancing {len(test) * args.takes} dances", flush=True)
                env = {**os.environ, "PYTHONPATH": str(root), "DANCENET_CACHE": str(Path(tmp) / f"cache_{tag}")}
                subprocess.run([sys.executable, __file__, "--dance", str(jobs), str(saved)], env=env, check=True,
                               cwd=root)
                z = np.load(saved)
                dances = [Motion(z[f"rot{i}"], z[f"root{i}"], fps, skeleton) for i in range(len(songs))]
                rows.append(DanceSet(f"{engine} @ {name}", f"{engine} at {name}", dances, styles, song_beats, {},
                                     songs))
    for row in list(rows[1:]):
        for a in range(0, args.takes, 2):
            keep = [i for i in range(len(songs)) if i % args.takes in (a, a + 1)]
            rows.append(row.only(keep, f"{row.name} (takes {a}, {a + 1})"))
    reference = reference_features([m.positions() for p, m in train if p.style in style_net.styles], fps,
                                   style_net)
    table = measure(rows, reference, fps, style_net, song_forms(test, data))
    result = {"rev": args.rev, "commit": commit, "takes": args.takes,
              "rows": {name: {k: r[k] for k in COLUMNS if k in r} for name, r in table.items()}}
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / f"comparison_{args.rev.replace('/', '_')}.json", json.dumps(result, indent=1) + "\n")
    for name, r in result["rows"].items():
        print(f"{name}: " + ", ".join(f"{k} {v:.4g}" for k, v in r.items()))
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--dance"]:
        dance(Path(sys.argv[2]), Path(sys.argv[3]))
    else:
        sys.exit(main())
