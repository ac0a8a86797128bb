"""A catalog's songs: what a caller names (files, folders, text and CSV lists with per-song settings) as the list
the runner dances, and what makes one song's files (`SongTask`)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from ..csvtable import cell_value, read_rows, read_text
from ..errors import DanceNetError
from ..music.audio import FFMPEG_FORMATS, SUPPORTED_FORMATS
from ..outputs import safe_stem
from ..request import options

AUDIO_SUFFIXES = frozenset(f".{s}" for s in (*SUPPORTED_FORMATS, *FFMPEG_FORMATS, "oga", "aif", "aiff"))
LIST_SUFFIXES = (".txt", ".m3u", ".m3u8", ".lst")


@dataclass(frozen=True)
class CatalogSong:
    """One song of a catalog: `label` as the user named it (the summaries say it), `path` where it is read (a
    cluster task reads a copy), `folder` its output folder's name (as read: its name made safe; as run: the
    folder it was given), `settings` its own request options over the batch's."""

    label: str
    path: Path
    folder: str
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def identity(self) -> str:
        """Which song a folder's record is for: the same name from any working folder."""
        return os.path.abspath(self.label)


class SongTask(Protocol):
    """What makes one song's files. Called in a worker process or on a cluster node, so it pickles."""

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        """The song's request options (the batch's, with the song's own over them)."""
        ...

    def outputs_key(self) -> dict[str, Any]:
        """What else changes the files (the extra formats asked for), for the request id."""
        ...

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        """Write the song's files into `folder` (created), all appearing together; returns `records.KEPT`'s
        fields and `files`, the names written. Raises DanceNetError (one line) for what the user can fix."""
        ...


def read_catalog(sources: Sequence[Path]) -> list[CatalogSong]:
    """The songs `sources` name, in order: an audio file; a folder (its audio files, subfolders included, by
    path); a list, a text file with a path a line (`#` comments) or a CSV with a `song` column and a column per
    setting (empty cells keep the batch's). Paths in a list are relative to its folder; a folder with no audio
    file in it stays in the list, to be reported as not a song. Each song's `folder` is its name made safe
    (`outputs.safe_stem`); `run_catalog` gives the songs of one name their own."""
    entries: list[tuple[str, Path, dict[str, Any]]] = []
    for source in sources:
        if source.is_dir():
            found = sorted(p for p in source.rglob("*") if p.suffix.lower() in AUDIO_SUFFIXES and p.is_file())
            entries += [(str(p), p, {}) for p in found] or [(str(source), source, {})]
        elif source.suffix.lower() == ".csv":
            entries += _read_csv(source)
        elif source.suffix.lower() in LIST_SUFFIXES:
            entries += _read_list(source)
        else:
            entries.append((str(source), source, {}))
    if not entries:
        raise DanceNetError("no songs given: name audio files, folders of them, or a list (.txt or .csv)")
    return [CatalogSong(label, path, safe_stem(path, "song"), settings) for label, path, settings in entries]


def _read_list(path: Path) -> list[tuple[str, Path, dict[str, Any]]]:
    lines = (line.strip() for line in read_text(path, "song list").splitlines())
    return [_entry(path, line, {}) for line in lines if line and not line.startswith("#")]


def _entry(listing: Path, song: str, settings: dict[str, Any]) -> tuple[str, Path, dict[str, Any]]:
    """A song named in a list, relative to the list's folder."""
    path = listing.parent / Path(song).expanduser()
    return str(path), path, settings


def _columns() -> dict[str, tuple[str, Any]]:
    """CSV column -> (request field, Option): the option's flag without dashes (`root-motion`, `start`), the
    field's name (`root_motion`, `start_s`) and `footfix` for `--no-footfix`."""
    columns = {}
    for name, _default, o in options():
        if o.flag is None:
            continue
        for column in {name, o.flag.lstrip("-").removeprefix("no-"), name.removesuffix("_s")}:
            columns[column] = (name, o)
            columns[column.replace("_", "-")] = (name, o)
    return columns


def _read_csv(path: Path) -> list[tuple[str, Path, dict[str, Any]]]:
    header, rows = read_rows(path, "song list")
    if not header:
        raise DanceNetError(f"{path} is empty: give a header row with a 'song' column")
    columns = _columns()
    if "song" not in header:
        raise DanceNetError(f"{path} has no 'song' column: its first row names the columns (song, style, ...)")
    unknown = [h for h in header if h != "song" and h not in columns]
    if unknown:
        raise DanceNetError(f"{path}: unknown column '{unknown[0]}'; the columns are song and "
                            f"{', '.join(sorted({n for n in columns if '_' not in n}))}")
    entries = []
    for number, cells in rows:
        if not cells.get("song"):
            raise DanceNetError(f"{path} line {number}: no song named")
        settings = {}
        for column, text in cells.items():
            if column != "song" and text:
                name, option = columns[column]
                settings[name] = _value(path, number, column, text, option.kind)
        entries.append(_entry(path, cells["song"], settings))
    return entries


def _value(path: Path, number: int, column: str, text: str, kind: type) -> Any:
    """A CSV cell as its setting's type; a folder or file is relative to the CSV's folder."""
    if column in ("library", "weights"):
        resolved = cell_value(path, number, column, text, Path)
        return resolved if kind is Path else str(resolved)
    return cell_value(path, number, column, text, kind)
