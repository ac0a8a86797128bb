"""`dancenet library build FOLDER`: analyse a folder of BVH clips into a motion library for `dancenet generate SONG
--engine library --library FOLDER` (cached by the folder's content: a second build of the same clips only reads)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ..library.build import build_library


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="library_command", required=True)
    b = sub.add_parser("build", help="read and analyse a folder of BVH clips (beats, tempo, bars, cut points)")
    b.add_argument("folder", type=Path, help="folder of .bvh clips (subfolders, or a manifest.csv, name styles)")
    b.add_argument("--force", action="store_true", help="build again even when this content was built before")
    b.set_defaults(handler=_cmd_build)


def _cmd_build(args: argparse.Namespace) -> int:
    t = time.perf_counter()
    library, path = build_library(args.folder, force=args.force)
    styles = sorted({s for s in library.styles if s}) or ["none"]
    meters = ", ".join(f"{m}/4: {int((library.meter == m).sum())}" for m in sorted(set(library.meter.tolist())))
    print(f"{library.num_clips} clips, {library.duration_s / 60:.1f} min, {len(library.beats)} beats "
          f"({int(library.downbeat.sum())} bars); tempo {np.min(library.tempo_bpm):.0f}-"
          f"{np.max(library.tempo_bpm):.0f} BPM; clips by meter {meters}; styles: {', '.join(styles)}; "
          f"{len(library.notes)} left out; {time.perf_counter() - t:.1f} s -> {path}")
    return 0
