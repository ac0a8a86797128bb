"""The one way the product writes a file: to a temporary name beside it, then renamed into place, so an
interruption (Ctrl-C, a kill, a full disk) leaves the old file or the new one, never half of one."""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from .errors import DanceNetError


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A fresh temporary path in `path`'s folder (same suffix, so writers that go by the extension still
    work); when the block ends it is synced and renamed onto `path`, or removed if the block failed.
    A failed write (disk full, no permission) becomes a one-line DanceNetError."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        yield tmp
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        reason = e.strerror or str(e)
        raise DanceNetError(f"cannot write {path}: {reason}; free some space or choose another folder") from e
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
