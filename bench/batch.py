"""`dancenet batch` throughput, printed as JSON: a catalog of songs made here (30 to 60 s each) danced from a cold
music cache by one worker, by two (`--jobs 2`), by a Ray of 2 CPUs that the command starts and stops
(`--cluster ray --jobs 2`) and by a running Ray cluster of this machine's 2 CPUs (`ray start --head --num-cpus=2`,
then `--cluster ray --address auto`), each run a fresh command, as a user runs it (start-up included).
Gives songs per minute, the ratios (jobs 2 over jobs 1, Ray over jobs 2: of the best runs, and round by round,
as this machine is shared), each worker's peak resident memory (from batch.json), whether the three runs wrote the same
bytes, and what the shared machine gave at the time: the load average, and how much more work two busy processes
got done than one (before each round and after the last; 2.0 on two idle cores), the most --jobs 2 can gain.

    .venv/bin/python bench/batch.py [--songs 20] [--repeats 1]
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
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
RUNS = {"jobs_1": ["--jobs", "1"], "jobs_2": ["--jobs", "2"], "ray_2cpu": ["--cluster", "ray", "--jobs", "2"],
        "ray_cluster_2cpu": ["--cluster", "ray", "--address", "auto"]}
RAY = Path(sys.executable).parent / "ray"


def make_songs(folder: Path, count: int, seed: int = 0) -> list[float]:
    """`count` songs of 30 to 60 s: chords on a pulse at 90 to 140 BPM, with a little noise, each its own."""
    import soundfile as sf

    rng = np.random.default_rng(seed)
    sr = 44100
    lengths = []
    for k in range(count):
        seconds, bpm = float(rng.uniform(30, 60)), float(rng.uniform(90, 140))
        t = np.arange(int(seconds * sr)) / sr
        beat = 60.0 / bpm
        root = 220 * 2 ** (np.floor(t / (4 * beat)) % 4 * rng.choice([3, 5, 7]) / 12)
        pulse = 0.5 + 0.5 * np.exp(-(t % beat) / 0.05)
        tone = sum(np.sin(2 * np.pi * root * r * t) for r in (1, 1.26, 1.5)) / 3
        y = 0.4 * pulse * tone + 0.01 * rng.standard_normal(len(t))
        sf.write(folder / f"song_{k:02d}.wav", y.astype(np.float32), sr)
        lengths.append(seconds)
    return lengths


def run(songs: Path, out: Path, flags: list[str], scratch: Path) -> dict:
    """One batch command from a cold music cache (numba's compiled code kept): its wall time and batch.json."""
    env = os.environ | cache(scratch, out.name)
    t, before = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-m", "dancenet_core.cli", "batch", str(songs), "-o", str(out), *flags],
                          cwd=REPO, env=env, capture_output=True, text=True)
    wall, after = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(flags)} failed: {proc.stderr.strip().splitlines()[-1:]}")
    rows = json.loads((out / "batch.json").read_text())["songs"]
    # CPU of the command and the processes it waited for: its workers (Ray's run under Ray's own daemons)
    return {"wall_s": round(wall, 2), "songs_per_minute": round(60 * len(rows) / wall, 2), "cpu_s": round(cpu, 1),
            "done": sum(r["status"] == "done" for r in rows),
            "worker_peak_memory_mb": max(r["peak_memory_mb"] for r in rows),
            "song_seconds_median": round(float(np.median([r["seconds"] for r in rows])), 2)}


SPIN = "i = 0\nwhile i < 20_000_000:\n    i += 1"


def two_over_one() -> float:
    """How much more work two busy processes get done than one, now (2.0 on two idle cores): the most `--jobs 2`
    can gain over `--jobs 1` while other jobs share the machine."""
    def rate(n: int) -> float:
        t = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(n)]
        for proc in procs:
            proc.wait()
        return n / (time.perf_counter() - t)

    return round(rate(2) / rate(1), 3)


def cache(scratch: Path, name: str) -> dict[str, str]:
    """A run's own cold music cache (its nodes', for a cluster), numba's compiled code shared."""
    return {"DANCENET_CACHE": str(scratch / f"cache-{name}"),
            "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR", str(Path.home() / ".cache" / "dancenet" / "numba"))}


@contextmanager
def ray_cluster(up: bool, env: dict[str, str]) -> Iterator[None]:
    """With `up`, a cluster as docs/catalog.md starts one, of this machine's 2 CPUs alone, running before the
    command as a cluster's users find it, its workers with the run's cache (`ray_2cpu` starts and stops a Ray of
    its own inside the command)."""
    if not up:
        yield
        return
    subprocess.run([str(RAY), "start", "--head", "--num-cpus=2", "--include-dashboard=false",
                    "--disable-usage-stats"], check=True, capture_output=True, env=os.environ | env)
    try:
        yield
    finally:
        subprocess.run([str(RAY), "stop"], check=False, capture_output=True)


def same_bytes(a: Path, b: Path) -> bool:
    """Every BVH and npz of run `a` equal, byte for byte, to run `b`'s."""
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.suffix in (".bvh", ".npz"))
    return bool(files) and all((a / f).read_bytes() == (b / f).read_bytes() for f in files)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--songs", type=int, default=20)
    p.add_argument("--repeats", type=int, default=1, help="rounds of the three runs (the best of each is kept)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="dancenet-bench-batch-") as tmp:
        scratch = Path(tmp)
        songs = scratch / "songs"
        songs.mkdir()
        lengths = make_songs(songs, args.songs)
        # numba's kernels compiled (or loaded) once before the timed runs, which then share them
        run(songs, scratch / "warm-up", ["--jobs", "1", "--end", "5"], scratch)
        load_before = os.getloadavg()[0]
        results: dict[str, list[dict]] = {name: [] for name in RUNS}
        machine = []
        for r in range(args.repeats):
            machine.append(two_over_one())
            for name, flags in RUNS.items():
                with ray_cluster(name == "ray_cluster_2cpu", cache(scratch, f"{name}-{r}")):
                    results[name].append(run(songs, scratch / f"{name}-{r}", flags, scratch))
        machine.append(two_over_one())
        load_after = os.getloadavg()[0]
        best = {name: max(runs, key=lambda x: x["songs_per_minute"]) for name, runs in results.items()}
        identical = all(same_bytes(scratch / "jobs_1-0", scratch / f"{name}-0") for name in list(RUNS)[1:])
    throughput = {name: b["songs_per_minute"] for name, b in best.items()}
    print(json.dumps({
        "command": "bench/batch.py " + " ".join(sys.argv[1:]),
        "machine": {"cpus": os.cpu_count(), "load_average_before": round(load_before, 2),
                    "load_average_after": round(load_after, 2),
                    "two_busy_processes_over_one": machine},
        "songs": args.songs, "song_seconds_total": round(sum(lengths), 1),
        "song_seconds_range": [round(min(lengths), 1), round(max(lengths), 1)],
        "jobs_2_over_jobs_1": round(throughput["jobs_2"] / throughput["jobs_1"], 3),
        "ray_over_jobs_2": round(throughput["ray_2cpu"] / throughput["jobs_2"], 3),
        "ray_cluster_over_jobs_2": round(throughput["ray_cluster_2cpu"] / throughput["jobs_2"], 3),
        "each_round": [{"jobs_2_over_jobs_1": round(j2["songs_per_minute"] / j1["songs_per_minute"], 3),
                        "ray_over_jobs_2": round(ray["songs_per_minute"] / j2["songs_per_minute"], 3),
                        "ray_cluster_over_jobs_2": round(cluster["songs_per_minute"] / j2["songs_per_minute"], 3),
                        "two_busy_processes_over_one_before": before}
                       for j1, j2, ray, cluster, before in zip(*results.values(), machine, strict=False)],
        "same_bytes_in_every_run": identical,
        "runs": best,
        "all_runs": results,
    }, indent=2))


if __name__ == "__main__":
    main()
