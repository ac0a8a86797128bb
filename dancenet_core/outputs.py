"""Where the product's output files go: names that stay inside the chosen folder, a folder checked for
writing before any long work, no silent replacement of files a user already has, and a run's files put in
place together, so runs into one folder never mix their outputs."""

from __future__ import annotations

import errno
import os
import re
import tempfile
import unicodedata
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from .atomic import fit_name, temp_path, write_error
from .errors import DanceNetError

# The longest stem a song's name gives, in UTF-8 bytes: room left for `_take100.blend` and Blender's `@`
# within the 255-byte limit on a file name (temporary names shorten themselves: atomic.temp_path).
MAX_STEM_BYTES = 200
# What some common file system refuses in a name (Windows' reserved characters, control characters, the
# separators), lone surrogates (bytes that are not UTF-8), and whitespace, which shells make awkward.
_REFUSED = re.compile(r'[\s<>:"/\\|?*\x00-\x1f\x7f\ud800-\udfff]+')
_DEVICES = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)), *(f"LPT{i}" for i in range(10))}


def safe_stem(path: str | Path, default: str = "dance") -> str:
    """A file-name stem from a song's file name (its extension dropped): `safe_name` of its stem."""
    return safe_name(Path(path).stem, default)


def safe_name(name: str, default: str) -> str:
    """A file-name stem from a name (every dot kept: "Rig v1.2" is not "Rig v1"), as close to it as file systems
    allow: letters of any script kept (NFC, so `café` is one name however it was typed), only refused characters
    and whitespace made `_`, no leading or trailing dots (never `..` or a hidden name, so outputs stay inside
    their folder), no Windows device name, and at most MAX_STEM_BYTES bytes (cut with a short hash, so long
    names stay distinct)."""
    stem = _REFUSED.sub("_", unicodedata.normalize("NFC", name)).strip(". ")
    if stem.upper() in _DEVICES:
        stem += "_"
    return fit_name(stem, MAX_STEM_BYTES) or default


def check_folder_writable(folder: Path) -> None:
    """Create `folder` if missing and prove a file can be written there (before minutes of work)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except FileExistsError as e:
        raise DanceNetError(f"the output folder {folder} is a file; choose a folder with -o") from e
    except OSError as e:
        raise DanceNetError(f"cannot write to the output folder {folder}: {e.strerror or e}; "
                            "choose another folder with -o") from e


def refuse_overwrite(paths: Iterable[Path]) -> None:
    """DanceNetError naming the first path that already exists, a dangling link included (the user passes
    --overwrite to replace it)."""
    existing = [p for p in paths if os.path.lexists(p)]
    if existing:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise DanceNetError(f"{existing[0]} already exists{more}; pass --overwrite to replace it, "
                            "or choose another output folder")


@contextmanager
def claimed_outputs(paths: Sequence[Path], overwrite: bool) -> Iterator[dict[Path, Path]]:
    """A temporary path for each of `paths` (all in one folder) for the block to write; when it ends they are
    renamed into place together, under the folder's lock and after checking again that none exists (unless
    `overwrite`). So concurrent runs into one folder never mix their files: without --overwrite the first
    to finish wins and the others end with one line; with it, the last one's whole set stays. The
    temporary files are removed however the block ends."""
    temps = {p: temp_path(p) for p in paths}
    try:
        yield temps
        with _folder_lock(paths[0].parent):
            if not overwrite:
                refuse_overwrite(paths)
            folders = [p for p in paths if p.is_dir() and not p.is_symlink()]
            if folders:
                raise DanceNetError(f"{folders[0]} is a folder; move it or choose another output folder")
            for path, tmp in temps.items():
                try:
                    os.replace(tmp, path)
                except OSError as e:
                    raise write_error(path, e) from e
    finally:
        for tmp in temps.values():
            tmp.unlink(missing_ok=True)


@contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """Hold `folder`'s lock (another process' claim waits for it); the system drops it when the process
    ends, however it ends. POSIX: the folder itself is locked; elsewhere a lock file in it."""
    if os.name == "posix":
        import fcntl

        fd = os.open(folder, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)
        return
    import msvcrt

    try:
        fd = os.open(folder / ".dancenet.lock", os.O_RDWR | os.O_CREAT)
    except OSError as e:
        raise _lock_error(folder, e) from e
    try:
        for attempt in range(_LOCK_TRIES):
            try:
                msvcrt.locking(fd, msvcrt.LK_LOCK, 1)
                break
            except OSError as e:  # EDEADLOCK: still held after LK_LOCK's 10 s; anything else will not pass
                if e.errno != errno.EDEADLOCK or attempt == _LOCK_TRIES - 1:
                    raise _lock_error(folder, e) from e
        try:
            yield
        finally:
            msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
    finally:
        os.close(fd)


# Windows' LK_LOCK tries for 10 s before it gives up; the holder only renames files, so a minute in all is
# another run that hangs.
_LOCK_TRIES = 6


def _lock_error(folder: Path, e: OSError) -> DanceNetError:
    return DanceNetError(f"cannot lock the output folder {folder}: {e.strerror or e}; if another dancenet run "
                         "writes there, wait for it, else choose another folder")

