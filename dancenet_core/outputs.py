"""Where the product's output files go: names that stay inside the chosen folder, a folder checked for
writing before any long work, and no silent replacement of files a user already has."""

from __future__ import annotations

import re
import tempfile
from collections.abc import Iterable
from pathlib import Path

from .errors import DanceNetError


def safe_stem(path: str | Path, default: str = "dance") -> str:
    """A file-name stem from a song's name: letters, digits, `_`, `-` and inner dots only, never a name
    that points elsewhere (`..`, hidden `.x`), so outputs stay inside the folder they are written to."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(path).stem).strip(".")
    return stem or default


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
    """DanceNetError naming the first path that already exists (the user passes --overwrite to replace it)."""
    existing = [p for p in paths if p.exists()]
    if existing:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise DanceNetError(f"{existing[0]} already exists{more}; pass --overwrite to replace it, "
                            "or choose another output folder")


def free_folder(parent: Path, name: str, taken: set[Path]) -> Path:
    """`parent/name`, or `parent/name_2`, `_3`, ... : the first that neither exists nor is in `taken`."""
    candidate, k = parent / name, 1
    while candidate in taken or candidate.exists():
        k += 1
        candidate = parent / f"{name}_{k}"
    return candidate
