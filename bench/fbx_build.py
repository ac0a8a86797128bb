"""FBX clips on the command line: `library build` of a folder of Mixamo-like FBX files with skin.

Each file is what tests/fbx_rigs.py writes with Blender's module: a `mixamorig:` rig of 65 bones (fingers and the
`_End` leaves) in centimetres under a 0.01 scale, a skinned mesh of about 10,000 vertices, 10 s of a made-up dance
at 30 fps. Prints JSON: the cold build of the folder (every file sampled by Blender's module in worker processes,
then read and analysed) with 1 and with 2 worker processes, seconds per file each (wall, and CPU seconds of the
process and its workers: on a shared machine the wall clock says more about the others), their ratio, the rebuild
of the unchanged folder (the built library read back) and a forced one (`--force`: every FBX file's sample read
from the cache, the clips read and analysed again), and the machine's load average.

    .venv/bin/python bench/fbx_build.py [--files 6] [--seconds 10] [--vertices 10000]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _cpu() -> float:
    """CPU seconds this process and its ended children (the workers) have used."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _build(folder: Path, workers: int, force: bool = False) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of a build of `folder`."""
    from dancenet_core.library.build import build_library

    t, cpu = time.perf_counter(), _cpu()
    library, _ = build_library(folder, force=force, workers=workers, report=lambda _line: None)
    seconds = time.perf_counter() - t
    assert not library.notes, library.notes
    return seconds, _cpu() - cpu


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
            cold, cpu = _build(folder, workers)
            out[f"cold_{workers}_worker_s"] = round(cold, 2)
            out[f"per_file_{workers}_worker_s"] = round(cold / args.files, 2)
            out[f"cpu_per_file_{workers}_worker_s"] = round(cpu / args.files, 2)
        out["ratio_1_over_2_workers"] = round(out["cold_1_worker_s"] / out["cold_2_worker_s"], 2)
        out["rebuild_s"] = round(_build(folder, 2)[0], 3)
        out["rebuild_forced_s"] = round(_build(folder, 2, force=True)[0], 2)
        out["load_average"] = round(os.getloadavg()[0], 1)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
