"""What a song's files were made for: a hash of the song's bytes, its settings, the weights and library it danced
with and the package's version (`request_id`), from digests remembered while a file's size and time stay the
same (`Digests`), so a catalog of tens of thousands of songs resumes without reading them all again."""

from __future__ import annotations

import hashlib
import json
import os
from contextlib import suppress
from pathlib import Path
from typing import Any

from .. import __version__
from ..atomic import write_text
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from ..library.store import folder_key
from ..request import check_song_path
from .songs import CatalogSong, SongTask

LIBRARY_ENGINE = "library"


class Digests:
    """sha256 digests of files by path, each kept with the size and modification time it was read at, and
    saved to `path` (JSON; None: this process only) so a later run reads only the files changed since."""

    def __init__(self, path: Path | None = None) -> None:
        self.path = path
        self.known: dict[str, list] = {}
        self.changed = False
        self.folders: dict[str, str] = {}  # a library folder's key, for this run
        if path is not None:
            try:
                known = json.loads(path.read_text(encoding="utf-8"))
                self.known = known if isinstance(known, dict) else {}
            except (OSError, ValueError):
                pass  # none yet, or damaged: read the files again

    def digest(self, path: str | Path) -> bytes:
        """The file's digest (`FileNotFoundError` and the like when it cannot be read)."""
        key = os.path.abspath(path)
        st = os.stat(key)
        known = self.known.get(key)
        if isinstance(known, list) and len(known) == 3 and known[:2] == [st.st_size, st.st_mtime_ns]:
            with suppress(TypeError, ValueError):  # a damaged entry is read again
                return bytes.fromhex(known[2])
        with open(key, "rb") as f:
            digest = hashlib.file_digest(f, "sha256").digest()
        self.known[key] = [st.st_size, st.st_mtime_ns, digest.hex()]
        self.changed = True
        return digest

    def described(self, path: str | Path) -> str:
        """The file's digest in hex, or that it is missing (its engine says so when the song runs)."""
        try:
            return self.digest(path).hex()
        except OSError:
            return f"missing:{path}"

    def folder(self, folder: Path) -> str:
        """A library folder's key (`store.folder_key`: its clips and manifest), once a run."""
        key = os.path.abspath(folder)
        if key not in self.folders:
            self.folders[key] = folder_key(folder, self.digest)
        return self.folders[key]

    def save(self) -> None:
        """Keep the digests for the next run; one that cannot be written costs only that (it reads the files)."""
        if self.path is None or not self.changed:
            return
        with suppress(OSError, DanceNetError):
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_text(self.path, json.dumps(self.known, separators=(",", ":")) + "\n")
            self.changed = False


def request_id(song: CatalogSong, task: SongTask, digests: Digests | None = None) -> str:
    """A hash of what makes the song's files: its bytes, its settings, the weights' bytes, the formats asked for
    and this version of the package. Raises DanceNetError when the song cannot be read."""
    check_song_path(song.path)
    digests = digests or Digests()
    settings = dict(task.settings(song))
    if settings.get("library") and settings.get("engine") != LIBRARY_ENGINE:
        settings["library"] = None  # only the library engine reads it
    h = hashlib.sha256(digests.described(song.path).encode())
    described = {"settings": settings, "outputs": task.outputs_key(),
                 "weights": weights_identity(settings, digests), "version": __version__}
    h.update(json.dumps(described, sort_keys=True, default=str).encode())
    return h.hexdigest()[:40]


def weights_identity(settings: dict[str, Any], digests: Digests | None = None) -> list[str]:
    """Digests of the files a request may read to dance: the shipped weights and library, the weights file it
    names and the library folder's clips and manifest (a missing one counts as missing: its engine says so when
    the song runs). The commercial mode reads none of the shipped files, and opens none for this either."""
    digests = digests or Digests()
    shipped = [] if settings.get("commercial") else sorted(WEIGHTS_DIR.glob("*.npz"))
    described = [digests.described(p) for p in shipped]
    if settings.get("weights"):
        described.append(digests.described(settings["weights"]))
    if settings.get("library"):
        folder = Path(settings["library"])
        described.append(f"folder:{digests.folder(folder)}" if folder.is_dir() else digests.described(folder))
    return described
