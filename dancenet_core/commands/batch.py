"""`dancenet batch SONGS... -o OUT`: a catalog of songs danced as `generate` dances one, each into OUT/<song>/,
in worker processes or on a Ray cluster (the `catalog` package runs them), with OUT/batch.csv and batch.json."""

from __future__ import annotations

import argparse
import importlib.util
import os
import pickle
import signal
import subprocess
import sys
import tempfile
from contextlib import suppress
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import IO, Any

from tqdm import tqdm

from ..catalog import CatalogSong, ray_module, read_catalog, run_catalog
from ..engines import get_engine
from ..errors import DanceNetError
from ..outputs import safe_stem
from ..request import DanceRequest, add_options, options_from
from .generate import Extra, dance_into, names

# The add-on's FBX writer, which keys a dance onto its rig with Blender's `bpy` module, run as a script in a
# process of its own (a source checkout has the add-on beside the package; the Blender extension is the add-on).
CHECKOUT = Path(__file__).resolve().parents[2]
FBX_WRITER = CHECKOUT / "blender_addon" / "fbx_takes.py"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("songs", nargs="+", type=Path, metavar="SONGS",
                   help="audio files, folders of them (subfolders included), or song lists: a text file with a "
                        "path a line, or a CSV with a 'song' column and a column per setting to change for that "
                        "song (style, seed, start, end, engine, library, temperature, takes, energy, fps, "
                        "root-motion, weights, footfix, commercial); paths relative to the list")
    p.add_argument("-o", "--out", type=Path, required=True,
                   help="output folder: OUT/<song>/ as `dancenet generate` writes it, OUT/batch.csv and batch.json")
    add_options(p, {"style": "auto (each song's style) or a style the engine knows, for every song"})
    p.add_argument("--render", action="store_true", help="also render each dance's preview video with the music")
    p.add_argument("--fbx", action="store_true",
                   help="also write each take as FBX on the add-on's default rig (needs the bpy module: "
                        'pip install ".[blender]" in a source checkout)')
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="songs danced at once, each in a worker process (default: the CPU count; on a cluster: "
                        "the CPUs of a Ray started here)")
    p.add_argument("--cluster", choices=["ray"], default=None,
                   help='run the songs as Ray tasks (pip install ".[cluster]"); see --address')
    p.add_argument("--address", default=None,
                   help="with --cluster ray: the cluster's address as Ray takes it (e.g. 10.0.0.5:6379 or auto; "
                        "default $RAY_ADDRESS, else a Ray started on this machine)")
    p.add_argument("--force", action="store_true",
                   help="dance again the songs already done for the same song, settings and weights")
    p.set_defaults(handler=run)


@dataclass(frozen=True)
class GenerateTask:
    """One song as `dancenet generate` makes it, with its settings over the batch's (a catalog.SongTask)."""

    defaults: dict[str, Any]
    render: bool = False
    fbx: bool = False

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        return {**self.defaults, **song.settings}

    def outputs_key(self) -> dict[str, Any]:
        return {"render": self.render, "fbx": self.fbx}

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        settings = self.settings(song)
        request = DanceRequest(song.path, **settings)
        request.check()
        args = argparse.Namespace(song=Path(song.label), out=folder, render=self.render, overwrite=True,
                                  continue_from=None, at=None, **settings)
        stem = safe_stem(song.path)
        fbx = [folder / f"{n}.fbx" for n in names(stem, request.takes)] if self.fbx else []
        _result, summary = dance_into(args, request, stem, extra=_fbx_extra(request, fbx) if fbx else None)
        return {"style": summary["style"], "tempo_bpm": summary["tempo_bpm"], "frames": summary["frames"],
                "duration_s": summary["duration_s"], "takes": summary["takes"],
                "files": [*summary["files"], f"{stem}.json", *(p.name for p in fbx)]}


def _fbx_extra(request: DanceRequest, paths: list[Path]) -> Extra:
    def write(result: Any, temp: dict[Path, Path]) -> None:
        write_fbx_takes(result, request, [temp[p] for p in paths])

    return paths, write


def write_fbx_takes(result: Any, request: DanceRequest, paths: list[Path]) -> None:
    """Each take of `result` (as danced) as an FBX file on the add-on's rig, one path per take, written by the
    add-on's FBX writer in a child process with Blender's bpy: neither bpy nor the add-on loads here. The writer
    is kept for this process' next song (Blender starts once per worker); its failure is one line."""
    check_fbx()
    writer, errors = _fbx_writer()
    try:
        pickle.dump((result, request, [str(p) for p in paths]), writer.stdin)
        writer.stdin.flush()
        reply = writer.stdout.readline().decode(errors="replace")
    except OSError:  # it died before it read the song
        reply = ""
    except BaseException:  # interrupted: its answer would be taken for the next song's
        _end_writer(writer, errors)
        raise
    if reply == "ok\n":
        return
    if reply.startswith("error "):
        raise DanceNetError(f"--fbx: {reply.removeprefix('error ').strip()}")
    code = _end_writer(writer, errors)
    errors.seek(0)
    said = [line for line in errors.read().decode(errors="replace").splitlines() if line.strip()]
    errors.close()
    ended = f"exit status {code}" if code >= 0 else _signal_name(-code)
    raise DanceNetError(f"--fbx: {said[-1].strip() if said else f'the FBX writer ended with {ended}'}")


def _end_writer(writer: subprocess.Popen, errors: IO[bytes]) -> int:
    """Stop the writer (the next song starts another); its exit status."""
    _fbx_writer.cache_clear()
    writer.kill()
    for pipe in (writer.stdin, writer.stdout):
        with suppress(OSError):
            pipe.close()
    return writer.wait()


@cache
def _fbx_writer() -> tuple[subprocess.Popen, IO[bytes]]:
    """The add-on's FBX writer as this process' child, which ends with it (its stdin closes; a kill takes it
    along), and the temporary file its stderr goes to, read for the last line if it dies."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(CHECKOUT), os.environ.get("PYTHONPATH")]))}
    errors = tempfile.TemporaryFile()
    process = subprocess.Popen([sys.executable, str(FBX_WRITER), str(os.getpid())], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, stderr=errors, env=env)
    return process, errors


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def check_fbx() -> None:
    """--fbx's needs, in one line each: Blender's bpy module and the add-on's FBX writer (neither imported)."""
    if importlib.util.find_spec("bpy") is None:
        raise DanceNetError('--fbx needs Blender\'s bpy module: pip install ".[blender]" (Python 3.11 for bpy 4.5), '
                            "or run the add-on's batch mode in Blender (blender_addon/batch.py --fbx)")
    if not FBX_WRITER.is_file():
        raise DanceNetError("--fbx keys each dance onto the add-on's rig, whose code (blender_addon/) comes with "
                            "the source checkout: run dancenet from an install of the checkout, or use the add-on's "
                            "batch mode: blender --background --python blender_addon/batch.py -- SONGS --out DIR --fbx")


def default_jobs() -> int:
    """The CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def run(args: argparse.Namespace) -> int:
    if args.jobs is not None and args.jobs < 1:
        raise DanceNetError(f"--jobs must be 1 or more, got {args.jobs}")
    if args.address is not None and args.cluster is None:
        raise DanceNetError("--address goes with --cluster ray")
    if args.fbx:
        check_fbx()
    if args.cluster == "ray":
        ray_module()
    defaults = options_from(args)
    everyone = DanceRequest(Path(), **defaults)  # the batch's settings, before a song is read
    everyone.check_settings()
    get_engine(everyone.engine).check(everyone)  # its weights load, its styles are known
    songs = read_catalog(args.songs)
    task = GenerateTask(defaults, args.render, args.fbx)
    bar = tqdm(total=len(songs), unit="song", dynamic_ncols=True, delay=0.5,
               bar_format="{l_bar}{bar} {n_fmt}/{total_fmt} songs [{elapsed}<{remaining}{postfix}]")
    counts = dict.fromkeys(("done", "skipped", "failed"), 0)

    def report(song: CatalogSong, row: dict[str, Any]) -> None:
        counts[row["status"]] += 1
        if row["status"] == "failed":
            bar.write(f"failed: {song.label}: {row['error']}", file=sys.stderr)
        if row["status"] == "skipped":  # done before: counted, not timed (the time left is the songs to dance)
            bar.total -= 1
        else:
            bar.update(1)
        bar.set_postfix_str(", ".join(f"{k} {v}" for k, v in counts.items() if v or k != "skipped"))

    try:
        status = run_catalog(songs, args.out, task, where=args.cluster or "local",
                             jobs=args.jobs or default_jobs(), address=args.address, force=args.force,
                             report=report)
    finally:
        bar.close()
    c = status.counts()
    print(f"{c['done']} danced, {c['skipped']} already done, {c['failed']} failed of {len(songs)} songs -> "
          f"{args.out} (batch.csv)")
    return 1 if c["failed"] else 0
