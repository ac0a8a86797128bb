"""The whole path as a user meets it, printed as JSON: `dancenet generate` on a 3-minute song in a fresh
process, first with an empty feature cache (cold) and then with its analysis cached, each split by stage
(the command's own JSON summary) beside the command's wall time (interpreter start and imports
included); and the demo (`make demo` after setup: generate plus preview video of the example song, from
an empty cache).

    .venv/bin/python bench/end_to_end.py [--skip-demo]

The 3-minute song is the first 180 s of DANCE_W_1 from $DANCENET_DATA (default <repo>/../shared/data),
else bench/analysis.py's synthetic song.
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

import soundfile as sf

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))

from analysis import synthetic_song  # noqa: E402


def three_minute_song(folder: Path) -> tuple[Path, str]:
    """(a 180-s song file, what it is)."""
    data = Path(os.environ.get("DANCENET_DATA", REPO.parent / "shared" / "data"))
    real = data / "dance_with_melody" / "DANCE_W_1.ogg"
    if not real.is_file():
        return synthetic_song(folder / "three_minutes.flac", 3.0), "synthetic"
    with sf.SoundFile(str(real)) as f:
        x = f.read(int(180 * f.samplerate), dtype="float32")
        sr = f.samplerate
    path = folder / "DANCE_W_1_3min.flac"
    sf.write(str(path), x, sr)
    return path, "first 180 s of DANCE_W_1"


def generate(song: Path, out: Path, cache: Path, *extra: str) -> dict:
    """Run `dancenet generate` in a fresh interpreter; its wall time and its summary's timings."""
    cmd = [sys.executable, "-m", "dancenet_core.cli", "generate", str(song), "-o", str(out), *extra]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, cwd=REPO, env=os.environ | {"DANCENET_CACHE": str(cache)})
    wall = time.perf_counter() - t
    summary = json.loads((out / f"{song.stem}.json").read_text())
    return {"wall_s": round(wall, 2), "stages_s": summary["timings_s"], "frames": summary["frames"],
            "beats": summary["beats"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--skip-demo", action="store_true", help="only the 3-minute song")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="dancenet-e2e-") as tmp:
        d = Path(tmp)
        song, kind = three_minute_song(d)
        result: dict = {"three_minute_song": {"song": kind,
                                              "cold": generate(song, d / "cold", d / "cache"),
                                              "cached": generate(song, d / "cached", d / "cache")}}
        if not args.skip_demo:
            result["demo"] = generate(REPO / "examples" / "example_song.ogg", d / "demo", d / "demo-cache", "--render")
            result["demo"]["note"] = "make demo after setup: generate --render on the example song, empty cache"
    result["load_average"] = [round(x, 2) for x in os.getloadavg()]
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
