"""`dancenet batch --fbx`'s FBX writer, run by the core's worker as a child process of its own, so Blender's
`bpy` module and the add-on never load in the core's processes:

    python blender_addon/fbx_takes.py PARENT_PID   < pickled (result, request, [TAKE1.fbx, ...]) per song

For each song it reads, it keys each take of the generation result (as danced, before `shape_takes`, as Generate
Dance keys it) onto the add-on's default rig, exports it to its path, in order, and answers one line on stdout:
`ok`, or `error ` and what went wrong. The paths are the worker's temporary names: the worker renames them into
place once all of the song's files are written. It runs until its stdin closes, and ends with its parent (a
killed worker takes it along)."""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path
from typing import Any


def write_fbx(result: Any, request: Any, paths: list[Path]) -> None:
    """Each take of a generated dance on the add-on's default rig as an FBX file, one path per take."""
    import bpy
    from batch import _addon, _scene_with_dance  # this script's folder is first on sys.path

    addon = _addon()
    context, applied = _scene_with_dance(addon, request, result)
    rig = bpy.data.objects[applied.rig]
    for name, path in zip(applied.actions, paths, strict=True):
        addon.takes.choose_take(rig, bpy.data.actions[name])
        addon.export.export_fbx(context, rig, path)


def main(argv: list[str]) -> int:
    answer = os.fdopen(os.dup(1), "w")  # the replies; Blender's chatter on stdout (the exporters name the
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # temporary files they write) goes nowhere
    from batch import _addon  # this script's folder is first on sys.path

    _addon()  # first, as batch mode loads it (an extension points the core's caches before the core loads)
    from dancenet_core.environment import end_with_parent
    from dancenet_core.errors import DanceNetError, first_line

    end_with_parent(int(argv[0]))
    while True:
        try:
            result, request, paths = pickle.load(sys.stdin.buffer)
        except EOFError:  # the worker has no more songs
            return 0
        try:
            write_fbx(result, request, [Path(p) for p in paths])
            answer.write("ok\n")
        except DanceNetError as e:
            answer.write(f"error {first_line(e)}\n")
        except Exception as e:  # a bug or an unforeseen file: one line for the song's record
            answer.write(f"error {type(e).__name__}: {first_line(e)}\n")
        answer.flush()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
