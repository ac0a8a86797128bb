"""Batch mode: dances for many songs, no interface.

    blender --background --python blender_addon/batch.py -- SONG... --out DIR [--fbx] [--bvh] [--render]
    python blender_addon/batch.py SONG... --out DIR [...]          (Blender as a Python module, pip bpy)

Each song gets its own folder DIR/<song>/ (DIR/<song>_2/ ... when that name is taken, by an earlier song
of the batch or a folder already there, unless --overwrite; a name never leads outside DIR) with
<song>.blend (rig, mannequin, the song's strip, beat markers, one action per take) and the exports asked
for. One summary line per song; the exit status is 1 if any song failed, after the others have finished.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import io
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import bpy


def _addon() -> SimpleNamespace:
    """The add-on modules batch mode uses, from the package this file sits in (`blender_addon` in a
    checkout, `dancenet` in an extension), imported from its folder: sys.path is left alone."""
    here = Path(__file__).resolve().parent
    if here.name not in sys.modules:
        spec = importlib.util.spec_from_file_location(here.name, here / "__init__.py",
                                                      submodule_search_locations=[str(here)])
        package = importlib.util.module_from_spec(spec)
        sys.modules[here.name] = package
        spec.loader.exec_module(package)
    modules = ("pipeline", "song", "export", "render")
    return SimpleNamespace(**{m: importlib.import_module(f"{here.name}.{m}") for m in modules})


def _resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT like 640x360, got {text!r}") from None
    if w < 16 or h < 16 or w % 2 or h % 2:
        raise argparse.ArgumentTypeError("width and height must be even and at least 16 (H.264)")
    return w, h


def parse_args(argv: list[str]) -> argparse.Namespace:
    from dancenet_core.request import add_options  # after the add-on has set up (see `main`)

    p = argparse.ArgumentParser(prog="batch.py", description="Generate dances for songs, one folder each.")
    p.add_argument("songs", nargs="+", type=Path, help="audio files")
    p.add_argument("--out", type=Path, required=True, help="output folder (one subfolder per song)")
    add_options(p, {"fps": "scene frame rate, slerp-resampled (default: the engine's own rate, no resampling)"})
    p.add_argument("--fbx", action="store_true", help="also write <song>.fbx")
    p.add_argument("--bvh", action="store_true", help="also write <song>.bvh")
    p.add_argument("--render", action="store_true", help="also render <song>.mp4 (Workbench, with the song)")
    p.add_argument("--resolution", type=_resolution, default=(640, 360), help="render size (default 640x360)")
    p.add_argument("--overwrite", action="store_true", help="reuse a song's existing folder, replacing its files")
    return p.parse_args(argv)


def run_song(
    addon: SimpleNamespace, song: Path, out: Path, args: argparse.Namespace, generator: Callable[..., Any] | None
) -> str:
    """Generate, save and export one song into the folder `out`; returns its summary line. Raises on failure."""
    from dancenet_core.request import DanceRequest, options_from

    pipeline = addon.pipeline
    started = time.perf_counter()
    song = addon.song.check_song(song)
    generator = generator or pipeline.load_generator()
    # An empty factory scene, the preferences kept: read_factory_settings resets them too, which disables the
    # installed extensions, and Blender then deletes their wheels (an installed DanceNet's core among them).
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    context = bpy.context
    scene = context.scene
    request = DanceRequest(song, **options_from(args))
    result = generator(request)
    scene.render.fps, scene.render.fps_base = args.fps or round(result.motions[0].fps), 1.0
    applied = pipeline.apply_result(context, pipeline.Plan(request), result)

    out.mkdir(parents=True, exist_ok=True)
    rig = bpy.data.objects[applied.rig]
    written = []
    with _quiet():
        if args.bvh:
            written.append(addon.export.export_bvh(context, rig, out / f"{out.name}.bvh"))
        if args.fbx:
            written.append(addon.export.export_fbx(context, rig, out / f"{out.name}.fbx"))
        if args.render:
            addon.render.setup_preview(scene, rig, out / f"{out.name}.mp4", args.resolution)
        blend = out / f"{out.name}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(blend))  # Blender writes `name.blend@` and renames it into place
        written.insert(0, blend)
        if args.render:
            written.append(addon.render.render_preview(scene))
    seconds = (applied.frame_end - applied.frame_start + 1) / addon.song.scene_fps(scene)
    takes = f"{len(applied.actions)} takes" if len(applied.actions) > 1 else "1 take"
    files = ", ".join(p.name for p in written)
    return (
        f"OK      {song.name}: {applied.style}, {seconds:.1f} s, {takes}, {result.tempo_bpm:.0f} BPM -> "
        f"{out} ({files}) in {time.perf_counter() - started:.1f} s"
    )


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Blender's exporters and renderer report the temporary names they write to (atomic.atomic_path) on
    stdout, from Python and from C: that chatter goes nowhere, so batch mode's output is its summary lines.
    Errors still arrive as exceptions and on stderr."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(io.StringIO()):
            os.dup2(devnull.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def main(argv: list[str] | None = None, generator: Callable[..., Any] | None = None) -> int:
    """Run the batch; `generator` defaults to the core's generate_dance."""
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    addon = _addon()  # first: in an extension it points the core's caches at its own folder before the core loads
    args = parse_args(argv)
    from dancenet_core.errors import DanceNetError
    from dancenet_core.outputs import check_folder_writable, free_folder, safe_stem

    try:
        check_folder_writable(args.out)
    except DanceNetError as e:
        print(f"FAILED  {e}", flush=True)
        return 1
    failures, taken = 0, set()
    for song in args.songs:
        stem = safe_stem(song, "song")
        out = args.out / stem
        if out in taken or (out.exists() and not args.overwrite):
            out = free_folder(args.out, stem, taken)
        taken.add(out)
        try:
            print(run_song(addon, song, out, args, generator), flush=True)
        except Exception as e:
            failures += 1
            if not isinstance(e, DanceNetError):
                traceback.print_exc()
            print(f"FAILED  {song.name}: {e}", flush=True)
    print(f"{len(args.songs) - failures} of {len(args.songs)} songs done", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
