"""Every benchmark in one run, printed as one JSON object: a `summary` with the headline figures and each
benchmark's full output under `details`. Each benchmark runs in its own fresh process (cold caches and
honest peak memory); speeds are ratios measured in the same run, because this machine is shared.

    .venv/bin/python bench/run.py [--quick]     (or: make bench)

--quick analyses a 1-minute song instead of a real 3.6-minute one and skips the 10-minute memory run and
the demo. The extension's bench (build, sizes, first Generate Dance in a fresh bpy 4.5 and 5.2) runs in both.
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

BENCH = Path(__file__).resolve().parent


def bench(script: str, *args: str, env: dict[str, str] | None = None) -> dict:
    """One benchmark's JSON, or {"error": its last line of stderr}."""
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, str(BENCH / script), *args], capture_output=True, text=True,
                          env=os.environ | (env or {}))
    if proc.returncode != 0:
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        return {"error": lines[-1] if lines else f"exit status {proc.returncode}"}
    out = proc.stdout
    result = json.loads(out[out.index("{") : out.rindex("}") + 1])  # Blender may print around the JSON
    return result | {"bench_wall_s": round(time.perf_counter() - t, 1)}


def summary(d: dict) -> dict:
    """The headline figures (speed and memory of analysis, generation, keying, rendering, the add-on), picked out of
    the benchmarks' outputs (None where one failed)."""

    def pick(name: str, *path: str) -> object:
        node: object = d.get(name, {})
        for key in path:
            node = node.get(key) if isinstance(node, dict) else None
        return node

    render = d.get("render", {})
    pyrender = render if render.get("engine") == "pyrender" else \
        next((r for r in render.get("results", []) if r.get("engine") == "pyrender"), {})
    return {
        "analysis_cold_s_per_audio_min": pick("analysis", "cold_s_per_audio_min"),
        "analysis_cached_s_per_audio_min": pick("analysis", "cached_s_per_audio_min"),
        "analysis_cold_over_cached": pick("analysis", "cold_over_cached"),
        "analysis_madmom_processors_cold_s_per_audio_min": pick("analysis", "madmom_processors_cold_s_per_audio_min"),
        "analysis_speedup_over_madmom_processors": pick("analysis", "speedup_over_madmom_processors"),
        "generation_cached_fps": pick("generation", "sampler", "cached_fps"),
        "generation_naive_fps": pick("generation", "sampler", "naive_fps"),
        "generation_cached_over_naive": pick("generation", "sampler", "cached_over_naive"),
        "three_minute_song_end_to_end_s_cold": pick("generation", "three_minute_song",
                                                    "first_run_s_with_cold_analysis"),
        "three_minute_song_end_to_end_s_cached_analysis": pick("generation", "three_minute_song",
                                                               "dance_s_with_cached_analysis"),
        "three_minute_song_numpy_over_torch_time_first_dance": pick("generation", "three_minute_song",
                                                                    "numpy_over_torch_time_first_dance"),
        "three_minute_song_numpy_over_torch_time_second_dance": pick("generation", "three_minute_song",
                                                                     "numpy_over_torch_time_second_dance"),
        "keyframes_3min_60fps_write_s": pick("keyframes", "foreach_set_write_s"),
        "keyframes_speedup_over_keyframe_insert": pick("keyframes", "speedup_write"),
        "pyrender_fps": pyrender.get("frames_per_s"),
        "pyrender_to_mp4_fps": pyrender.get("video_frames_per_s"),
        "pyrender_before_fps": pick("render", "before", "frames_per_s"),
        "pyrender_before_to_mp4_fps": pick("render", "before", "video_frames_per_s"),
        "pyrender_speedup_to_mp4": pyrender.get("speedup_video"),
        "generate_3min_song_cold_wall_s": pick("end_to_end", "three_minute_song", "cold", "wall_s"),
        "generate_3min_song_cold_stages_s": pick("end_to_end", "three_minute_song", "cold", "stages_s"),
        "generate_3min_song_cached_wall_s": pick("end_to_end", "three_minute_song", "cached", "wall_s"),
        "generate_3min_song_cached_stages_s": pick("end_to_end", "three_minute_song", "cached", "stages_s"),
        "demo_wall_s_after_setup": pick("end_to_end", "demo", "wall_s"),
        "peak_rss_mb_ten_minute_song": pick("generation", "ten_minute_song", "peak_rss_mb"),
        "ten_minute_song_numpy_over_torch_peak_rss": pick("generation", "ten_minute_song", "numpy_over_torch_peak_rss"),
        "peak_rss_mib_analysis": pick("analysis", "peak_rss_mib"),
        "addon_zip_mb": {p: v.get("zip_mb") for p, v in pick("addon", "sizes").items()}
        if pick("addon", "sizes") else None,
        "addon_first_generate_s": {v: {case: r.get(case, {}).get("first_generate_s")
                                       for case in ("clicked_at_once", "clicked_after_warm_up")}
                                   for v, r in (pick("addon", "first_click") or {}).items()},
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="shorter songs, no 10-minute memory run")
    args = p.parse_args()
    t = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="dancenet-bench-") as scratch:
        blender_home = {"HOME": scratch, "BLENDER_USER_CONFIG": f"{scratch}/config",
                        "BLENDER_USER_SCRIPTS": f"{scratch}/scripts", "BLENDER_USER_DATAFILES": f"{scratch}/data"}
        details = {
            "analysis": bench("analysis.py", *(["--synthetic-minutes", "1"] if args.quick else []),
                              env={"DANCENET_CACHE": f"{scratch}/cache"}),
            # A fresh cache, so the 3-minute song's first run really includes its music analysis.
            "generation": bench("generation.py", *(["--skip-memory"] if args.quick else []),
                                env={"DANCENET_CACHE": f"{scratch}/cache-generation"}),
            "keyframes": bench("keyframes.py", env=blender_home),
            "render": bench("render.py", "--engine", "pyrender"),
            "end_to_end": bench("end_to_end.py", *(["--skip-demo"] if args.quick else [])),
            # The extension built and installed into a fresh bpy 4.5 and 5.2 (each bench its own scratch folders).
            "addon": bench("addon_first_click.py", "--pythons",
                           *(str(BENCH.parent / v / "bin" / "python") for v in (".venv", ".venv-blender52"))),
        }
    result = {"summary": summary(details), "details": details, "wall_s": round(time.perf_counter() - t, 1),
              "cpu_count": os.cpu_count(), "load_average": [round(x, 2) for x in os.getloadavg()]}
    print(json.dumps(result, indent=1))
    return 1 if any("error" in v for v in details.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
