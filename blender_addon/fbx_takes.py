"""`dancenet batch --fbx`'s FBX writer, run by the core's worker as a child process of its own, so Blender's
`bpy` module and the add-on never load in the core's processes:

    python blender_addon/fbx_takes.py PARENT_PID TAKE1.fbx [TAKE2.fbx ...] < pickled (result, request)

It keys each take of the generation result (as danced, before `shape_takes`, as Generate Dance keys it) onto the
add-on's default rig and exports it to its path, in order. The paths are the worker's temporary names: the
worker renames them into place once all of the song's files are written. A failure is one line on stderr and
exit status 1; the process ends with its parent (a killed worker takes it along)."""

from __future__ import annotations

import pickle
import sys
from pathlib import Path
from typing import Any

import bpy
from batch import _addon, _quiet, _scene_with_dance  # this script's folder is first on sys.path


def write_fbx(result: Any, request: Any, paths: list[Path]) -> None:
    """Each take of a generated dance on the add-on's default rig as an FBX file, one path per take."""
    addon = _addon()
    context, applied = _scene_with_dance(addon, request, result)
    rig = bpy.data.objects[applied.rig]
    with _quiet():
        for name, path in zip(applied.actions, paths, strict=True):
            addon.takes.choose_take(rig, bpy.data.actions[name])
            addon.export.export_fbx(context, rig, path)


def main(argv: list[str]) -> int:
    _addon()  # first, as batch mode loads it (an extension points the core's caches before the core loads)
    from dancenet_core.environment import end_with_parent
    from dancenet_core.errors import DanceNetError, first_line

    end_with_parent(int(argv[0]))
    try:
        result, request = pickle.load(sys.stdin.buffer)
        write_fbx(result, request, [Path(p) for p in argv[1:]])
    except DanceNetError as e:
        print(e, file=sys.stderr)
        return 1
    except Exception as e:  # a bug or an unforeseen file: one line for the song's record
        print(f"{type(e).__name__}: {first_line(e)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
