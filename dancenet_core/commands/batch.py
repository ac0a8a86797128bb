"""`dancenet batch SONGS... -o OUT`: a catalog of songs danced as `generate` dances one, each into OUT/<song>/,
in worker processes or on a Ray cluster (the `catalog` package runs them), with OUT/batch.csv and batch.json."""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..catalog import CatalogSong, ray_module, read_catalog, run_catalog
from ..engines import get_engine
from ..errors import DanceNetError
from ..outputs import safe_stem
from ..request import DanceRequest, add_options, options_from
from .generate import Extra, dance_into, names

# The add-on's batch mode, which keys a dance onto its rig in Blender's `bpy` module (a source checkout has it
# beside the package; the Blender extension is the add-on itself).
ADDON_BATCH = Path(__file__).resolve().parents[2] / "blender_addon" / "batch.py"


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
        _addon_batch().write_fbx(result, request, [temp[p] for p in paths])

    return paths, write


@cache
def _addon_batch() -> Any:
    """The add-on's batch module (`write_fbx`), loaded from its file once per process."""
    check_fbx()
    spec = importlib.util.spec_from_file_location("dancenet_addon_batch", ADDON_BATCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def check_fbx() -> None:
    """--fbx's needs, in one line each: Blender's bpy module and the add-on's code."""
    if importlib.util.find_spec("bpy") is None:
        raise DanceNetError('--fbx needs Blender\'s bpy module: pip install ".[blender]" (Python 3.11 for bpy 4.5), '
                            "or run the add-on's batch mode in Blender (blender_addon/batch.py --fbx)")
    if not ADDON_BATCH.is_file():
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
