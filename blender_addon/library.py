"""The motion library from the panel: the chosen Library folder, whether it is built, Build Library's work (the
core's torch-free `dancenet_core.library.build`, on a worker thread), and the Style menu's styles of a library."""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import bpy

from dancenet_core.errors import DanceNetError
from dancenet_core.progress import StageProgress
from dancenet_core.request import DanceRequest

from .job import error_message
from .pipeline import panel_settings


def chosen_folder(props: bpy.types.PropertyGroup) -> Path | None:
    """The panel's Library folder, absolute ("//" is beside the .blend), or None for the shipped library."""
    return panel_settings(props)["library"]


def library_styles(folder: Path | None) -> list[str]:
    """The styles of a built motion library's clips (None: the shipped one), or [] while it is missing or not
    built (Generate Dance then says why): the Style menu's choices for the library engine."""
    try:
        from dancenet_core.engines import get_engine

        return get_engine("library").styles(DanceRequest(Path(), library=folder))
    except (ImportError, DanceNetError, OSError):
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
        return "No BVH clips in it", "ERROR"
    return ("Built", "CHECKMARK") if built else ("Not built yet", "INFO")


def summary(library: Any) -> str:
    """Build Library's report: clips, minutes and styles read, and what was left out (with the first reason)."""
    styles = ", ".join(sorted({s for s in library.styles if s})) or "none"
    line = f"Built library: {library.num_clips} clips, {library.duration_s / 60:.1f} min, styles {styles}"
    if library.notes:
        files = f"{len(library.notes)} file{'s' if len(library.notes) > 1 else ''}"
        line += f"; left out {files}: {library.notes[0].removeprefix('left out ')}"
    return line


def build(folder: Path, progress: StageProgress, should_cancel: Callable[[], bool]) -> str:
    """Build the library of `folder` (or find it built) and say what it holds. Never touches bpy: Build Library
    runs it on a worker thread (`job.Job`)."""
    from dancenet_core.library.build import build_library

    library, _path = build_library(folder, progress=progress, should_cancel=should_cancel)
    return summary(library)


def build_now(folder: Path) -> str:
    """`build` on the calling thread (scripts, background mode, tests); any failure as one line."""
    try:
        return build(folder, lambda _stage, _fraction: None, lambda: False)
    except DanceNetError:
        raise
    except Exception as e:
        raise DanceNetError(error_message(e, "Library build")) from e
