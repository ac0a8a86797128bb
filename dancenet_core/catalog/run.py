"""The runner: a catalog danced into an output folder, the songs done before for the same request skipped, the
others danced in this process, in worker processes or on a Ray cluster, the status table written as they end."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from ..atomic import remove_leftovers
from ..errors import DanceNetError
from ..outputs import check_folder_writable
from .cluster import check_reachable, ray_module, run_ray
from .dance import dance_song
from .folders import assign_folders
from .identity import Digests, request_id
from .local import run_local
from .records import DIGESTS, RECORDS, Status, finished
from .songs import CatalogSong, SongTask

Where = Literal["inline", "local", "ray"]
Report = Callable[[CatalogSong, dict[str, Any]], None]


def run_catalog(songs: list[CatalogSong], out: Path, task: SongTask, *, where: Where = "local", jobs: int = 1,
                address: str | None = None, force: bool = False, report: Report | None = None) -> Status:
    """Dance every song of the catalog into `out`/<folder>, skipping those already done for the same request
    (unless `force`), and return the status table (also written to `out`). `report` hears of each song as it
    ends, skipped ones first."""
    if where == "ray":  # a missing Ray, or a cluster that does not answer, is said before anything is written
        ray_module()
        check_reachable(address or os.environ.get("RAY_ADDRESS"))
    check_folder_writable(out)
    remove_leftovers(out)
    remove_leftovers(out / RECORDS)
    songs = assign_folders(out, songs)
    status = Status(out, songs)
    tell = report or (lambda _song, _row: None)

    def ended(i: int, row: dict[str, Any]) -> None:
        status.set(i, row)
        status.write(now=False)
        tell(songs[i], {**row, **status.rows[i]})

    plan = []  # (index, song, request id, the row of a song that cannot be read)
    digests = Digests(out / RECORDS / DIGESTS)
    try:
        for i, song in enumerate(songs):
            try:
                rid = request_id(song, task, digests)
            except DanceNetError as e:
                plan.append((i, song, "", {"status": "failed", "error": str(e)}))
                continue
            kept = None if force else finished(out, song, rid)
            if kept is not None:
                status.set(i, {**kept, "status": "skipped"})
                tell(song, status.rows[i])
            else:
                plan.append((i, song, rid, None))
    finally:
        digests.save()  # what was read, for the next run, however this one ends
    status.write()
    try:
        if where == "inline":  # one after the other, in the list's order
            for i, song, rid, unread in plan:
                ended(i, unread or dance_song(task, song, out, rid))
            return status
        for i, _song, _rid, unread in plan:
            if unread:
                ended(i, unread)
        todo = [(i, song, rid) for i, song, rid, unread in plan if not unread]
        if where == "local":
            run_local(todo, task, out, jobs, ended)
        else:
            run_ray(todo, task, out, jobs, address, ended)
        return status
    finally:
        status.write()
