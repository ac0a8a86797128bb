"""A user's CSV file read one way wherever the product reads one (a song catalog, a motion library's manifest):
as a spreadsheet saves it (UTF-8 with or without Excel's byte-order mark), its headers compared without case or
surrounding spaces, and each cell read as the type of the setting it gives."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from .errors import DanceNetError, first_line

YES = frozenset({"true", "yes", "1", "on"})
NO = frozenset({"false", "no", "0", "off"})


def read_text(path: Path, what: str) -> str:
    """The text of a list the user wrote (`what` names it in the error), without a byte-order mark."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DanceNetError(f"{what} not found: {path} (check the path)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise DanceNetError(f"cannot read the {what} {path}: {first_line(e)}") from e


def read_rows(path: Path, what: str) -> tuple[list[str], list[tuple[int, dict[str, str]]]]:
    """The CSV's headers (lower case, stripped; the empty ones a trailing comma leaves dropped) and its rows as
    (line number, header -> stripped cell), rows with no cell left out. Empty file: no headers, no rows."""
    rows = list(csv.reader(io.StringIO(read_text(path, what))))
    if not rows:
        return [], []
    header = [h.strip().lower() for h in rows[0]]
    while header and not header[-1]:
        header.pop()
    table = []
    for number, row in enumerate(rows[1:], 2):
        cells = {h: c.strip() for h, c in zip(header, row, strict=False)}
        if any(cells.values()):
            table.append((number, cells))
    return header, table


def cell_value(path: Path, line: int, column: str, text: str, kind: type) -> Any:
    """A cell as `kind`: yes/no for a bool, a whole number for an int (`3.0` too), a path relative to the
    CSV's folder for a Path, else `kind(text)`; anything else one line that names the file, line and column."""
    if kind is bool:
        if text.lower() not in YES | NO:
            raise DanceNetError(f"{path} line {line}: {column} is yes or no, got '{text}'")
        return text.lower() in YES
    if kind is Path:
        return path.parent / Path(text).expanduser()
    try:
        return kind(float(text)) if kind is int and float(text).is_integer() else kind(text)
    except ValueError:
        raise DanceNetError(f"{path} line {line}: {column} must be a {'whole ' if kind is int else ''}number, "
                            f"got '{text}'") from None
