"""One song danced into its folder, whatever happens: its row of the status table, with its time and memory."""

from __future__ import annotations

import sys
import time
from contextlib import suppress
from pathlib import Path
from typing import Any

from ..atomic import remove_leftovers
from ..errors import DanceNetError, first_line
from .records import write_record
from .songs import CatalogSong, SongTask

PROC_SELF = Path("/proc/self")


def dance_song(task: SongTask, song: CatalogSong, out: Path, rid: str) -> dict[str, Any]:
    """Run `task` on one song into its folder, whatever happens: the row of the status table for it. Its record
    says it begun before the first file, and complete after the last."""
    t0 = time.perf_counter()
    measured = reset_peak_memory()
    row: dict[str, Any] = {}
    folder = out / song.folder
    try:
        folder.mkdir(parents=True, exist_ok=True)
        remove_leftovers(folder)
        write_record(out, song, rid, None)
        row = task(song, folder)
        write_record(out, song, rid, row)
        row["status"] = "done"
    except DanceNetError as e:
        row = {"status": "failed", "error": str(e)}
    except Exception as e:  # a bug or an unforeseen file: this song's line, and the others go on
        row = {"status": "failed", "error": f"{type(e).__name__}: {first_line(e)}"}
    if row["status"] == "failed":
        with suppress(OSError):
            folder.rmdir()  # a folder left empty
    row["seconds"] = round(time.perf_counter() - t0, 2)
    row["peak_memory_mb"] = peak_memory_mb() if measured else process_peak_memory_mb()
    return row


def reset_peak_memory() -> bool:
    """Start this process' peak resident memory again from what it holds now (Linux: `clear_refs`), so the peak
    read after a song is the song's; False where the system cannot."""
    try:
        (PROC_SELF / "clear_refs").write_text("5")
    except OSError:
        return False
    return peak_memory_mb() is not None


def peak_memory_mb() -> float | None:
    """This process' peak resident memory since `reset_peak_memory` (Linux's VmHWM), None where not said."""
    try:
        status = (PROC_SELF / "status").read_text()
    except OSError:
        return None
    for line in status.splitlines():
        if line.startswith("VmHWM:"):
            return round(int(line.split()[1]) / 2**10, 1)  # kB
    return None


def process_peak_memory_mb() -> float | None:
    """This process' peak resident memory since it started (None where the system does not say): where the
    peak cannot be started again, a worker's row holds the most of its songs so far."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (2**20 if sys.platform == "darwin" else 2**10), 1)  # bytes on macOS, KiB elsewhere
