"""Batch mode: dances for many songs, no interface.

    blender --background --python blender_addon/batch.py -- SONGS... --out DIR [--fbx] [--bvh] [--render]
    python blender_addon/batch.py SONGS... --out DIR [...]          (Blender as a Python module, pip bpy)

SONGS are audio files, folders of them or song lists (a text file with a path a line, or a CSV with a column
per setting), as `dancenet batch` takes them: the same catalog runner (`dancenet_core.catalog`) runs them here,
one after the other in Blender's process. Each song gets its own folder DIR/<song>/ (DIR/<song>_2/ ... when that
name is taken, by an earlier song of the batch or a folder that is not the batch's; a name never leads outside
DIR) with <song>.blend (rig, mannequin, the song's strip, beat markers, one action per take) and the exports asked
for. A song already done for the same song, settings and weights is skipped (--force dances it again), so a
batch that was stopped goes on where it stopped. One line per song, DIR/batch.csv and batch.json; the exit status
is 1 if any song failed, after the others have finished.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import io
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import bpy

if TYPE_CHECKING:
    from dancenet_core.catalog import CatalogSong


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
    modules = ("pipeline", "preferences", "song", "export", "render", "takes")
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
    p.add_argument("songs", nargs="+", type=Path,
                   help="audio files, folders of them, or song lists (a path a line, or a CSV with a column a "
                        "setting)")
    p.add_argument("--out", type=Path, required=True, help="output folder (one subfolder per song)")
    add_options(p, {"fps": "scene frame rate, slerp-resampled (default: the engine's own rate, no resampling)"})
    p.add_argument("--fbx", action="store_true", help="also write <song>.fbx")
    p.add_argument("--bvh", action="store_true", help="also write <song>.bvh")
    p.add_argument("--render", action="store_true", help="also render <song>.mp4 (Workbench, with the song)")
    p.add_argument("--resolution", type=_resolution, default=(640, 360), help="render size (default 640x360)")
    p.add_argument("--force", action="store_true", help="dance again the songs done before for the same settings")
    return p.parse_args(argv)


@dataclass(frozen=True)
class BlenderTask:
    """One song's .blend and exports (a `dancenet_core.catalog.SongTask`, run in this process)."""

    addon: SimpleNamespace
    args: argparse.Namespace
    generator: Callable[..., Any] | None

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        """The command line's settings, the song list's for this song over them, and Commercial Use over both
        where the add-on's preference asks for it (Commercial Use only)."""
        from dancenet_core.request import options_from

        settings = {**options_from(self.args), **song.settings}
        return settings | {"commercial": True} if self.addon.preferences.commercial_only() else settings

    def outputs_key(self) -> dict[str, Any]:
        return {"blend": True, "fbx": self.args.fbx, "bvh": self.args.bvh, "render": self.args.render,
                "resolution": list(self.args.resolution)}

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        return run_song(self.addon, song, folder, self.args, self.settings(song), self.generator)


def run_song(addon: SimpleNamespace, song: CatalogSong, out: Path, args: argparse.Namespace,
             settings: dict[str, Any], generator: Callable[..., Any] | None) -> dict[str, Any]:
    """Generate, save and export one song into the folder `out`; returns its row of the status table (the
    catalog's fields and `files`). Raises on failure."""
    from dancenet_core.request import DanceRequest

    path = addon.song.check_song(song.path)
    generator = generator or addon.pipeline.load_generator()
    request = DanceRequest(path, **settings)
    result = generator(request)
    context, applied = _scene_with_dance(addon, request, result)
    scene = context.scene
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
    return {"style": applied.style, "tempo_bpm": round(result.tempo_bpm, 2),
            "frames": applied.frame_end - applied.frame_start + 1,
            "duration_s": round((applied.frame_end - applied.frame_start + 1) / addon.song.scene_fps(scene), 3),
            "takes": len(applied.actions), "files": [p.name for p in written]}


def _scene_with_dance(addon: SimpleNamespace, request: Any, result: Any) -> tuple[Any, Any]:
    """A new empty scene at the request's frame rate (else the dance's own) with the dance on the default rig."""
    # An empty factory scene, the preferences kept: read_factory_settings resets them too, which disables the
    # installed extensions, and Blender then deletes their wheels (an installed DanceNet's core among them).
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    context = bpy.context
    context.scene.render.fps, context.scene.render.fps_base = request.fps or round(result.motions[0].fps), 1.0
    return context, addon.pipeline.apply_result(context, addon.pipeline.Plan(request), result)


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
    from dancenet_core.catalog import read_catalog, run_catalog
    from dancenet_core.errors import DanceNetError

    def report(song: CatalogSong, row: dict[str, Any]) -> None:
        name, folder = Path(song.label).name, args.out / song.folder
        if row["status"] == "done":
            takes = f"{row['takes']} takes" if row["takes"] > 1 else "1 take"
            print(f"OK      {name}: {row['style']}, {row['duration_s']:.1f} s, {takes}, {row['tempo_bpm']:.0f} BPM -> "
                  f"{folder} ({', '.join(row['files'])}) in {row['seconds']:.1f} s", flush=True)
        elif row["status"] == "skipped":
            print(f"SKIPPED {name}: done before for the same song, settings and weights -> {folder}", flush=True)
        else:
            print(f"FAILED  {name}: {row['error']}", flush=True)

    try:
        songs = read_catalog(args.songs)
        status = run_catalog(songs, args.out, BlenderTask(addon, args, generator), where="inline", force=args.force,
                             report=report)
    except DanceNetError as e:
        print(f"FAILED  {e}", flush=True)
        return 1
    counts = status.counts()
    print(f"{counts['done'] + counts['skipped']} of {len(songs)} songs done", flush=True)
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
