"""FBX clips on the command line: `library build` of a folder of Mixamo-like FBX files with skin.

Each file is what tests/fbx_rigs.py writes with Blender's module: a `mixamorig:` rig of 65 bones (fingers and the
`_End` leaves) in centimetres under a 0.01 scale, a skinned mesh of about 10,000 vertices, 10 s of a made-up dance
at 30 fps. Prints JSON: the cold build of the folder (every file sampled by Blender's module in worker processes,
then read and analysed) with 1 and with 2 worker processes, seconds per file each, their ratio, and the rebuild of
the unchanged folder (the built library read back) and a forced one (`--force`: every FBX file's sample read from
the cache, the clips read and analysed again).

    .venv/bin/python bench/fbx_build.py [--files 6] [--seconds 10] [--vertices 10000]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _build(folder: Path, workers: int, force: bool = False) -> float:
    from dancenet_core.library.build import build_library

    t = time.perf_counter()
    library, _ = build_library(folder, force=force, workers=workers, report=lambda _line: None)
    seconds = time.perf_counter() - t
    assert not library.notes, library.notes
    return seconds


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--files", type=int, default=6)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--vertices", type=int, default=10000)
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "clips"
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
        subprocess.run([sys.executable, str(REPO / "tests" / "fbx_rigs.py"), str(folder), "--copies", str(args.files),
                        "--seconds", str(args.seconds), "--vertices", str(args.vertices)],
                       check=True, env=env, capture_output=True)
        out: dict[str, object] = {"files": args.files, "seconds_of_motion": args.seconds, "fps": 30,
                                  "vertices": args.vertices, "bones": 65,
                                  "mb_per_file": round(sum(f.stat().st_size for f in folder.iterdir()) / 1e6
                                                       / args.files, 2), "cpus": os.cpu_count()}
        for workers in (1, 2):
            os.environ["DANCENET_CACHE"] = str(Path(tmp) / f"cache{workers}")
            cold = _build(folder, workers)
            out[f"cold_{workers}_worker_s"] = round(cold, 2)
            out[f"per_file_{workers}_worker_s"] = round(cold / args.files, 2)
        out["ratio_1_over_2_workers"] = round(out["cold_1_worker_s"] / out["cold_2_worker_s"], 2)
        out["rebuild_s"] = round(_build(folder, 2), 3)
        out["rebuild_forced_s"] = round(_build(folder, 2, force=True), 2)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
