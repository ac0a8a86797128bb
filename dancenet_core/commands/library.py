"""`dancenet library build FOLDER`: analyse a folder of BVH and FBX clips into a motion library for `dancenet generate
SONG --engine library --library FOLDER` (cached by the folder's content: a second build of the same clips only
reads). FBX files are read by Blender's Python module where it is installed (the `blender` extra), each cached by
its content; clips are read side by side (`--jobs`), with a progress bar."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..errors import DanceNetError
from ..library.analysis import UNSURE
from ..library.build import build_library
from ..library.store import MotionLibrary


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="library_command", required=True)
    b = sub.add_parser("build", help="read and analyse a folder of BVH and FBX clips (beats, tempo, bars, cuts)")
    b.add_argument("folder", type=Path, help="folder of .bvh and .fbx clips (subfolders, or a manifest.csv, name "
                                             "styles); FBX needs Blender's module: pip install 'dancenet[blender]'")
    b.add_argument("--force", action="store_true", help="build again even when this content was built before")
    b.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="clips read side by side (default: $DANCENET_WORKERS or 2)")
    b.add_argument("--commercial", action="store_true",
                   help="say what a commercial use of this library needs (the build itself uses no trained weights "
                        "in either mode; docs/licence.md)")
    b.set_defaults(handler=_cmd_build)


def _cmd_build(args: argparse.Namespace) -> int:
    if args.jobs is not None and args.jobs < 1:
        raise DanceNetError(f"--jobs must be 1 or more, got {args.jobs}")
    t = time.perf_counter()
    bars: dict[str, tqdm] = {}

    def progress(stage: str, fraction: float) -> None:
        """One bar for sampling FBX files, one for reading the clips (shown when a build takes a while)."""
        kind = stage.split(" ", 1)[0]
        if kind not in bars:
            for bar in bars.values():
                bar.close()
            bars[kind] = tqdm(total=1000, desc=kind, unit="", delay=0.5, leave=False, file=sys.stderr,
                              bar_format="{desc} {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]")
        bars[kind].update(round(1000 * fraction) - bars[kind].n)

    try:
        library, path = build_library(args.folder, force=args.force, progress=progress, workers=args.jobs,
                                      report=tqdm.write)
    finally:
        for bar in bars.values():
            bar.close()
    print(clip_table(library))
    unsure = [n for n, c in zip(library.names, library.confidence, strict=True) if c < UNSURE]
    if unsure:
        print(f"unsure of the tempo or meter of {len(unsure)} clip{'s' if len(unsure) > 1 else ''} "
              f"({', '.join(unsure[:5])}{'...' if len(unsure) > 5 else ''}): give them in manifest.csv (columns "
              "file, bpm, meter) if they are wrong")
    styles = sorted({s for s in library.styles if s}) or ["none"]
    meters = ", ".join(f"{m}/4: {int((library.meter == m).sum())}" for m in sorted(set(library.meter.tolist())))
    print(f"{library.num_clips} clips, {library.duration_s / 60:.1f} min, {len(library.beats)} beats "
          f"({int(library.downbeat.sum())} bars); tempo {np.min(library.tempo_bpm):.0f}-"
          f"{np.max(library.tempo_bpm):.0f} BPM; clips by meter {meters}; styles: {', '.join(styles)}; "
          f"{len(library.notes)} left out; {time.perf_counter() - t:.1f} s -> {path}")
    if args.commercial:
        print(f"commercial use: `dancenet generate SONG --commercial --engine library --library {args.folder}` "
              "dances these clips with no non-commercial part (no style classifier, no learned match); the clips' "
              "own terms are yours to check")
    return 0


def clip_table(library: MotionLibrary) -> str:
    """One line per clip: its name, the skeleton's convention it was read in, style, length, tempo, meter, confidence
    and what they were read from."""
    width = min(max(len(n) for n in library.names), 40)
    skeletons = library.skeletons or [""] * library.num_clips
    lines = [f"{'clip':{width}s}  {'skeleton':16s} {'style':10s} {'length':>7s} {'tempo':>9s} {'meter':>5s} "
             f"{'sure':>5s}  from"]
    for c, name in enumerate(library.names):
        seconds = (library.clip_starts[c + 1] - library.clip_starts[c]) / library.fps
        lines.append(f"{name[:width]:{width}s}  {skeletons[c][:16] or '-':16s} {library.styles[c][:10] or '-':10s} "
                     f"{seconds:6.1f}s {library.tempo_bpm[c]:5.1f} BPM {library.meter[c]:3d}/4 "
                     f"{library.confidence[c]:5.2f}  {library.source[c]}")
    return "\n".join(lines)
