"""A catalog's songs danced by worker processes of this machine (`--jobs`), one song at a time each."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
from collections import deque
from collections.abc import Callable
from contextlib import suppress
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from ..atomic import remove_leftovers
from ..environment import end_with_parent
from .dance import dance_song
from .records import RECORDS
from .songs import CatalogSong, SongTask

Ended = Callable[[int, dict[str, Any]], None]
Item = tuple[int, CatalogSong, str]  # (index in the catalog, song, request id)


def run_local(todo: list[Item], task: SongTask, out: Path, jobs: int, ended: Ended) -> None:
    """Up to `jobs` worker processes (spawned: the same start on every platform, and Blender's `bpy`, which
    `--fbx` loads, is not safe to fork), each given one song at a time; one that dies is replaced, its song
    reported and its unfinished files removed. However this ends (Ctrl-C, SIGTERM), the workers are stopped and
    their unfinished files removed."""
    context = mp.get_context("spawn")
    queue = deque(todo)
    busy: dict[Connection, tuple[mp.process.BaseProcess, Item]] = {}

    def start() -> None:
        ours, theirs = context.Pipe()
        process = context.Process(target=_worker, args=(theirs, os.getpid(), task, str(out)),
                                  name="dancenet-batch")
        process.start()
        theirs.close()
        give(ours, process)

    def give(conn: Connection, process: mp.process.BaseProcess) -> None:
        item = queue.popleft() if queue else None
        try:
            conn.send(item)
        except OSError:  # the worker died between two songs: the song goes to another
            if item is not None:
                queue.appendleft(item)
                start()
            item = None
        if item is None:
            process.join()
            conn.close()
        else:
            busy[conn] = (process, item)

    try:
        for _ in range(min(max(1, jobs), len(queue))):
            start()
        while busy:
            for conn in wait(list(busy)):
                process, item = busy.pop(conn)
                try:
                    i, row = conn.recv()
                except (EOFError, OSError):  # the worker died with its song
                    process.join()
                    conn.close()
                    _remove_unfinished(out, item[1])
                    ended(item[0], {"status": "failed", "error": _death(process.exitcode)})
                    if queue:
                        start()
                    continue
                ended(i, row)
                give(conn, process)
    finally:
        _stop(out, busy, ended)


def _remove_unfinished(out: Path, song: CatalogSong) -> None:
    """The temporary files of a song whose worker is gone (each name says its process: `atomic.remove_leftovers`),
    which may be large (`--render`, `--fbx`)."""
    remove_leftovers(out / song.folder)
    remove_leftovers(out / RECORDS)


def _stop(out: Path, busy: dict[Connection, tuple[mp.process.BaseProcess, Item]], ended: Ended) -> None:
    """Stop the workers still dancing (Ctrl-C, SIGTERM, an error here) at once, and remove their unfinished
    files. Killed, not asked: a signal that Python turns into an exception can land where it is lost (a C
    library's callback), and the files are removed here either way. A song a worker finished before the stop,
    its row still in the pipe (workers that start together end their first songs together), is reported done,
    as the next run finds it."""
    for process, _item in busy.values():
        process.kill()
    for conn, (process, (_i, song, _rid)) in busy.items():
        process.join()
        with suppress(EOFError, OSError):  # nothing sent, or a row cut off by the kill
            if conn.poll():
                ended(*conn.recv())
        _remove_unfinished(out, song)


def _death(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        name = signal.Signals(-exitcode).name if -exitcode in signal.valid_signals() else str(-exitcode)
        more = " (out of memory? try fewer --jobs)" if -exitcode == signal.SIGKILL else ""
        return f"the worker process dancing this song was killed by {name}{more}; run the batch again to retry it"
    return f"the worker process dancing this song ended (exit status {exitcode}); run the batch again to retry it"


def _worker(conn: Connection, parent: int, task: SongTask, out: str) -> None:
    """A worker process: songs from `conn` until None, one row back for each. It ends with the batch; the batch
    stops it (`_stop`)."""
    end_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the batch's to answer (`_stop`)
    # Songs run side by side, each on one core, as a Ray task is given one: the music analysis of each in this
    # process alone, and BLAS on one thread for what runs outside `one_blas_thread` too (writing the files).
    os.environ["DANCENET_WORKERS"] = "1"
    from threadpoolctl import threadpool_limits

    threadpool_limits(1, user_api="blas")
    try:
        while (item := conn.recv()) is not None:
            i, song, rid = item
            conn.send((i, dance_song(task, song, Path(out), rid)))
    except (EOFError, BrokenPipeError):  # the batch is gone
        pass
