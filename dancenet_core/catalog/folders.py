"""Each song's output folder: its name, made distinct from the other songs', the batch's own files and the
user's folders."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from .records import RECORDS, TABLES, read_record
from .songs import CatalogSong

RESERVED = frozenset(name.casefold() for name in (RECORDS, *TABLES))  # the batch's own, beside the songs'


def assign_folders(out: Path, songs: list[CatalogSong]) -> list[CatalogSong]:
    """Each song's folder: its name, else `_2`, `_3`...: the first that is not the status table's, that no
    earlier song of the list took and that is free (missing, or empty) or this song's (its record says so). A
    folder of the user's, or another song's, is never written into, and the same list in the same folder gives
    each song the same folder."""
    taken: set[str] = set(RESERVED)
    assigned = []
    for song in songs:
        name, k = song.folder, 1
        while name.casefold() in taken or not _ours(out, name, song):  # case-insensitive file systems too
            k += 1
            name = f"{song.folder}_{k}"
        taken.add(name.casefold())
        assigned.append(replace(song, folder=name))
    return assigned


def _ours(out: Path, name: str, song: CatalogSong) -> bool:
    folder = out / name
    if not os.path.lexists(folder):
        return True
    record = read_record(out, name)
    if record is not None:
        return record.get("song") == song.identity
    return folder.is_dir() and not folder.is_symlink() and not any(folder.iterdir())
