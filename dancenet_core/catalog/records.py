"""What a catalog's output folder says about its songs: each song folder's record in OUT/.batch/ (the song and the
request its files were made for, begun before the first file and complete after the last) and the status table,
`batch.csv` and `batch.json`, one row a song."""

from __future__ import annotations

import csv
import io
import json
import time
from pathlib import Path
from typing import Any

from ..atomic import write_text
from .songs import CatalogSong

RECORDS = ".batch"  # in the output folder: <song folder>.json, the song and request its files were made for
DIGESTS = "digests"  # in RECORDS: the songs' and weights' digests by size and time (no `.json`: not a record)
TABLES = ("batch.csv", "batch.json")  # in the output folder, beside the song folders
COLUMNS = ("song", "folder", "status", "style", "tempo_bpm", "frames", "duration_s", "takes", "seconds",
           "peak_memory_mb", "error")
# What a finished song's record keeps for the status table of a later run that skips it.
KEPT = ("style", "tempo_bpm", "frames", "duration_s", "takes")


def read_record(out: Path, folder: str) -> dict[str, Any] | None:
    try:
        record = json.loads((out / RECORDS / f"{folder}.json").read_text(encoding="utf-8"))
        return record if isinstance(record, dict) else None
    except (OSError, ValueError):
        return None


def write_record(out: Path, song: CatalogSong, rid: str, row: dict[str, Any] | None) -> None:
    """The song's record: begun (no row: its files are being made) or complete (the row it ended with)."""
    record: dict[str, Any] = {"song": song.identity, "request_id": rid, "complete": row is not None}
    if row is not None:
        record |= {"files": row["files"], "kept": {k: row.get(k) for k in KEPT}}
    (out / RECORDS).mkdir(exist_ok=True)
    write_text(out / RECORDS / f"{song.folder}.json", json.dumps(record, indent=1) + "\n")


def finished(out: Path, song: CatalogSong, rid: str) -> dict[str, Any] | None:
    """The kept fields of the song if its folder holds all its files for request `rid`, else None (also for a
    record edited by hand into something else)."""
    record = read_record(out, song.folder)
    try:
        if record["complete"] and record["request_id"] == rid and \
                all((out / song.folder / name).is_file() for name in record["files"]):
            return dict(record["kept"])
    except (TypeError, KeyError, ValueError):
        pass
    return None


class Status:
    """The status table, one row a song in the catalog's order, rewritten whole (`batch.csv`, `batch.json`): as
    songs end, at most once every `EVERY_S` seconds (a catalog of 40,000 songs is megabytes a write), and at the
    end however the run ends."""

    EVERY_S = 1.0

    def __init__(self, out: Path, songs: list[CatalogSong]) -> None:
        self.out = out
        self.rows = [{"song": s.label, "folder": s.folder, "status": "pending"} for s in songs]
        self.written = -self.EVERY_S

    def set(self, index: int, row: dict[str, Any]) -> None:
        self.rows[index] = {**self.rows[index], **{k: v for k, v in row.items() if k in COLUMNS}}

    def counts(self) -> dict[str, int]:
        counts = dict.fromkeys(("done", "skipped", "failed", "pending"), 0)
        for row in self.rows:
            counts[row["status"]] += 1
        return counts

    def write(self, now: bool = True) -> None:
        """Write the table (`now`), or only if `EVERY_S` seconds have passed since it was last written."""
        if not now and time.monotonic() - self.written < self.EVERY_S:
            return
        self.written = time.monotonic()
        table = [{c: row.get(c) for c in COLUMNS} for row in self.rows]
        csv_name, json_name = TABLES
        write_text(self.out / json_name, json.dumps({"counts": self.counts(), "songs": table}, indent=1) + "\n")
        text = io.StringIO()
        writer = csv.DictWriter(text, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows({c: "" if v is None else v for c, v in row.items()} for row in table)
        write_text(self.out / csv_name, text.getvalue())
