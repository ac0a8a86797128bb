"""The motion library from the panel: its source (the Library folder, or the armature actions in this file), whether
it is built, Build Library's work (rigs sampled in Blender, `rigclips`, a step at a time on the main thread; then the
core's torch-free `dancenet_core.library.build` on a worker thread), and the Style menu's styles of a library."""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache, partial
from pathlib import Path
from typing import Any

import bpy

from dancenet_core.errors import DanceNetError
from dancenet_core.request import DanceRequest

from . import job, rigchoice, rigclips, song
from .job import error_message
from .panelsettings import panel_settings


def chosen_folder(props: bpy.types.PropertyGroup) -> Path | None:
    """The panel's Library folder, absolute ("//" is beside the .blend), or None for the shipped library."""
    return panel_settings(props)["library"]


@lru_cache(maxsize=4)
def _drawn_key(signature: tuple) -> str:
    """The actions' content key for the panel: read again only when their quick signature changes."""
    fps, actions, _counts = signature
    return rigclips.actions_key(list(actions), fps)


def chosen_library(props: bpy.types.PropertyGroup, drawn: bool = False) -> Path | None:
    """What the library engine dances from: the Library folder, or, with the file's armature actions as the source,
    where their library is cached (built or not: their content says where), or None for the shipped library.
    `drawn` (the panel, the Style menu): the actions' key as last read while their quick signature is the same."""
    if props.library_source == "ACTIONS":
        from dancenet_core.library.store import built_path

        actions, fps = rigclips.file_actions()[0], song.scene_fps(props.id_data)
        key = _drawn_key(rigclips.actions_signature(actions, fps)) if drawn else rigclips.actions_key(actions, fps)
        return built_path(key)
    return chosen_folder(props)


def library_styles(folder: Path | None) -> list[str]:
    """The styles of a built motion library's clips (None: the shipped one), or [] while it is missing or not
    built (Generate Dance then says why): the Style menu's choices for the library engine. An ImportError (a
    broken install) is raised: the Style menu shows its reason."""
    try:
        from dancenet_core.engines import get_engine

        return get_engine("library").styles(DanceRequest(Path(), library=folder))
    except (DanceNetError, OSError):
        return []


@lru_cache(maxsize=16)
def _built_path(folder: Path, signature: tuple[tuple[str, int, int], ...]) -> Path:
    """Where the library of `folder` is cached, for its files as `signature` (name, size, time) has them: the
    content key reads every clip, too slow to do each time the panel is drawn."""
    from dancenet_core.library.store import library_path

    return library_path(folder)


def folder_state(folder: Path) -> tuple[str, str]:
    """What the panel says beside Build Library about `folder`: a short text and its icon."""
    from dancenet_core.library.store import clip_files

    if not folder.is_dir():
        return "Folder not found", "ERROR"
    try:
        files = clip_files(folder)
        stats = [(p, p.stat()) for p in [*files, folder / "manifest.csv"] if p.is_file()]
        built = _built_path(folder, tuple((str(p), s.st_size, s.st_mtime_ns) for p, s in stats)).is_file()
    except OSError as e:  # a clip removed or unreadable while the panel draws
        return f"Cannot read the folder: {e.strerror}", "ERROR"
    if not files:
        return "No BVH or FBX clips in it", "ERROR"
    return ("Built", "CHECKMARK") if built else ("Not built yet", "INFO")


def actions_state(props: bpy.types.PropertyGroup) -> tuple[str, str]:
    """What the panel says beside Build Library about the file's armature actions: how many, and whether built."""
    actions, _notes = rigclips.file_actions()
    if not actions:
        return "No action animates a humanoid armature", "ERROR"
    built = chosen_library(props, drawn=True)
    count = f"{len(actions)} action{'s' if len(actions) > 1 else ''}"
    return (f"{count}, built", "CHECKMARK") if built is not None and built.is_file() else (f"{count}, not built yet",
                                                                                           "INFO")


def summary(library: Any, what: str = "file") -> str:
    """Build Library's report: clips, minutes and styles read, and what was left out (with the first reason)."""
    styles = ", ".join(sorted({s for s in library.styles if s})) or "none"
    line = f"Built library: {library.num_clips} clips, {library.duration_s / 60:.1f} min, styles {styles}"
    if library.notes:
        left = f"{len(library.notes)} {what}{'s' if len(library.notes) > 1 else ''}"
        line += f"; left out {left}: {library.notes[0].removeprefix('left out ')}"
    return song.readable(line)


def _noted(name: str, sample: Callable[[], Any]) -> Any:
    """A sampled clip, or the one line saying why clip `name` could not be sampled (one the build leaves out;
    without a name: an FBX file's, which the build names)."""
    try:
        return sample()
    except DanceNetError as e:
        why = str(e)
    except Exception as e:
        why = error_message(e, "Sampling")
    return f"{name}: {why}" if name else why


def build_job(props: bpy.types.PropertyGroup) -> job.Staged:
    """Build Library's job for the panel's source: the rigs to sample in Blender first (a folder's FBX files, the
    file's actions; none when that content is built already), then the core's build on a worker thread."""
    from dancenet_core.library.build import build_armature_library, build_library, is_fbx
    from dancenet_core.library.store import built_path, clip_files, library_path

    if props.library_source == "ACTIONS":
        actions, notes = rigclips.file_actions()
        fps = song.scene_fps(props.id_data)
        key = rigclips.actions_key(actions, fps)
        todo = [] if built_path(key).is_file() else actions
        steps = [(f"sampling {a.name}", partial(_noted, a.name, partial(rigclips.sample_action, a, fps))) for a in todo]

        def from_actions(results: list[Any]) -> job.Work:
            return lambda progress, should_cancel: summary(build_armature_library(
                results, key, notes, progress=progress, should_cancel=should_cancel)[0], "action")

        return job.Staged(steps, from_actions, "dancenet-build-library")
    folder = chosen_folder(props)
    if folder is None:
        raise DanceNetError("Choose the Library folder of BVH clips to build (the shipped library needs no build)")
    fbx = [] if not folder.is_dir() or library_path(folder).is_file() else [f for f in clip_files(folder) if is_fbx(f)]
    steps = [(f"importing {f.name}", partial(_noted, "", partial(rigclips.sample_fbx, f))) for f in fbx]

    def from_folder(results: list[Any]) -> job.Work:
        sampled = dict(zip(fbx, results, strict=True))
        return lambda progress, should_cancel: summary(build_library(
            folder, progress=progress, should_cancel=should_cancel, fbx_samples=sampled,
            saved_maps=rigchoice.saved_maps_dir())[0])

    return job.Staged(steps, from_folder, "dancenet-build-library")


def build_now(props: bpy.types.PropertyGroup) -> str:
    """Build Library on the calling thread (scripts, background mode, tests); any failure as one line."""
    try:
        return build_job(props).run_now()
    except DanceNetError:
        raise
    except Exception as e:
        raise DanceNetError(error_message(e, "Library build")) from e
