"""The one way the product writes a file: to a temporary name beside it, then renamed into place, so an
interruption (Ctrl-C, a kill, a full disk) leaves the old file or the new one, never half of one."""

from __future__ import annotations

import errno
import hashlib
import os
import re
import secrets
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO

from .errors import DanceNetError

# The longest file name (not path) common file systems take, in bytes: ext4, APFS, NTFS (in UTF-16 units,
# never fewer than UTF-8 bytes' worth of letters), so a name that fits in UTF-8 bytes fits everywhere.
NAME_MAX_BYTES = 255
# A temporary name: `.<stem>.<pid>.<8 hex>.tmp<suffix>`, the pid telling a later run whose leftover it is.
_TEMP = re.compile(r"^\..*\.(\d+)\.[0-9a-f]{8}\.tmp(\.[^.]*)?$", re.DOTALL)


def fit_name(stem: str, limit: int) -> str:
    """`stem` if it takes at most `limit` bytes in UTF-8, else its start cut on a character boundary plus
    `-` and 8 hex digits of a hash of the whole, so a long name stays recognisable and distinct."""
    raw = stem.encode("utf-8", "surrogateescape")
    if len(raw) <= limit:
        return stem
    digest = hashlib.sha256(raw).hexdigest()[:8]
    head = raw[: max(0, limit - len(digest) - 1)].decode("utf-8", "ignore")
    return f"{head}-{digest}"


def temp_path(path: str | Path) -> Path:
    """A fresh hidden temporary name in `path`'s folder, with its suffix (writers that go by the extension
    still work), short enough for the file system whatever the length of `path`'s name."""
    path = Path(path)
    tail = f".{os.getpid()}.{secrets.token_hex(4)}.tmp{path.suffix}"
    return path.with_name("." + fit_name(path.stem, NAME_MAX_BYTES - 1 - len(tail.encode())) + tail)


def remove_leftovers(folder: str | Path) -> None:
    """Remove temporary files that runs killed outright (SIGKILL, power loss) left in `folder`: those whose
    process is gone. A live process' files are left alone; so is everything on a platform where a process
    cannot be asked whether it lives without being signalled (Windows)."""
    if os.name != "posix":
        return
    with suppress(OSError):
        for entry in os.scandir(folder):
            match = _TEMP.match(entry.name)
            if match and entry.is_file(follow_symlinks=False) and not _alive(int(match.group(1))):
                with suppress(OSError):
                    os.unlink(entry.path)


def _alive(pid: int) -> bool:
    """Whether process `pid` still runs (POSIX: signal 0 checks without sending anything). A zombie does not:
    a worker killed with its batch stays one until the init process reaps it, which in a container can take
    a second or more, and a run started at once must still clear its leftovers."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):  # someone else's process, or no pid at all: not ours to judge
        return True
    return not _zombie(pid)


def _zombie(pid: int) -> bool:
    """Whether `pid` has ended and waits to be reaped (Linux's /proc; elsewhere none is reported)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[-1].split()[:1] == ["Z"]


def write_error(path: Path, e: OSError) -> DanceNetError:
    """One line that says why `path` could not be written and what to do about it."""
    reason = e.strerror or str(e)
    if e.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        advice = "free some space or choose another folder"
    elif e.errno == errno.EISDIR:
        advice = "a folder has that name; move it or choose another folder"
    elif e.errno == errno.ENAMETOOLONG:
        advice = "choose a shorter name or folder"
    elif e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        advice = "choose a folder you can write to"
    else:
        advice = "choose another folder"
    return DanceNetError(f"cannot write {path}: {reason}; {advice}")


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A fresh temporary path in `path`'s folder (`temp_path`); when the block ends it is synced and renamed
    onto `path`, or removed if the block failed. A failed write (disk full, no permission) becomes a
    one-line DanceNetError."""
    path = Path(path)
    tmp = temp_path(path)
    try:
        yield tmp
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise write_error(path, e) from e
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_open(path: str | Path, mode: str = "w", **kwargs: object) -> Iterator[IO]:
    """`open(path, mode)` whose contents appear at `path` only once the block has finished."""
    with atomic_path(path) as tmp, open(tmp, mode, **kwargs) as f:  # type: ignore[call-overload]
        yield f


def write_text(path: str | Path, text: str) -> None:
    """Replace `path` with `text` (UTF-8) in one step."""
    with atomic_open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)
