"""A song catalog danced in one run: `dancenet batch` and the add-on's batch mode share this runner.

The songs come from files, folders and lists (`read_catalog`); each gets a folder of its own in the output
folder, named after it, and the task a caller gives (`SongTask`) writes that folder's files. The runner adds
what a catalog needs around it:

- isolation: a song that fails (a bad file, an exception, a worker process killed by the system) is reported
  and the others go on;
- resuming: each song folder has a record in OUT/.batch/ of the song and the request its files were made for
  (a hash of the song's bytes, its settings and the weights' bytes: `request_id`), marked complete after the
  files, so a song whose files are all there for the same request is skipped and any other (never started,
  cut off by a kill, made for other settings) is made again; a killed run leaves whole files only (each is
  renamed into place);
- the user's files: a folder with no record of ours is never written into; the song takes the next free name;
- a status table, `batch.csv` and `batch.json` in the output folder, rewritten whole as songs end;
- where the songs run: in this process (`inline`: Blender), in `--jobs` worker processes of this machine
  (`local`), or as tasks on a Ray cluster (`ray`), where the driver reads each song and sends its bytes, and
  the task sends the files back for the driver to write: the nodes share no folder.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import multiprocessing as mp
import os
import signal
import socket
import sys
import tempfile
import time
from collections import deque
from collections.abc import Callable, Sequence
from contextlib import suppress
from dataclasses import dataclass, field, replace
from functools import cache
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Literal, Protocol

from . import __version__
from .atomic import remove_leftovers, write_text
from .environment import WEIGHTS_DIR, end_with_parent
from .errors import DanceNetError, first_line
from .music.audio import FFMPEG_FORMATS, SUPPORTED_FORMATS
from .outputs import check_folder_writable, claimed_outputs, safe_stem
from .request import check_song_path, options

RECORDS = ".batch"  # in the output folder: <song folder>.json, the song and request its files were made for
COLUMNS = ("song", "folder", "status", "style", "tempo_bpm", "frames", "duration_s", "takes", "seconds",
           "peak_memory_mb", "error")
# What a finished song's record keeps for the status table of a later run that skips it.
KEPT = ("style", "tempo_bpm", "frames", "duration_s", "takes")
AUDIO_SUFFIXES = frozenset(f".{s}" for s in (*SUPPORTED_FORMATS, *FFMPEG_FORMATS, "oga", "aif", "aiff"))
LIST_SUFFIXES = (".txt", ".m3u", ".m3u8", ".lst")
Where = Literal["inline", "local", "ray"]


@dataclass(frozen=True)
class CatalogSong:
    """One song of a catalog: `label` as the user named it (the summaries say it), `path` where it is read (a
    cluster task reads a copy), `folder` its output folder's name (as read: its name made safe; as run: the
    folder it was given), `settings` its own request options over the batch's."""

    label: str
    path: Path
    folder: str
    settings: dict[str, Any] = field(default_factory=dict)


class SongTask(Protocol):
    """What makes one song's files. Called in a worker process or on a cluster node, so it pickles."""

    def settings(self, song: CatalogSong) -> dict[str, Any]:
        """The song's request options (the batch's, with the song's own over them)."""
        ...

    def outputs_key(self) -> dict[str, Any]:
        """What else changes the files (the extra formats asked for), for the request id."""
        ...

    def __call__(self, song: CatalogSong, folder: Path) -> dict[str, Any]:
        """Write the song's files into `folder` (created), all appearing together; returns `KEPT`'s fields and
        `files`, the names written. Raises DanceNetError (one line) for what the user can fix."""
        ...


# ---------------------------------------------------------------------------------------------- the song list


def read_catalog(sources: Sequence[Path]) -> list[CatalogSong]:
    """The songs `sources` name, in order: an audio file; a folder (its audio files, subfolders included, by
    path); a list, a text file with a path a line (`#` comments) or a CSV with a `song` column and a column per
    setting (empty cells keep the batch's). Paths in a list are relative to its folder; a folder with no audio
    file in it stays in the list, to be reported as not a song. Each song's `folder` is its name made safe
    (`outputs.safe_stem`); `run_catalog` gives the songs of one name their own."""
    entries: list[tuple[str, Path, dict[str, Any]]] = []
    for source in sources:
        if source.is_dir():
            found = sorted(p for p in source.rglob("*") if p.suffix.lower() in AUDIO_SUFFIXES and p.is_file())
            entries += [(str(p), p, {}) for p in found] or [(str(source), source, {})]
        elif source.suffix.lower() == ".csv":
            entries += _read_csv(source)
        elif source.suffix.lower() in LIST_SUFFIXES:
            entries += _read_list(source)
        else:
            entries.append((str(source), source, {}))
    if not entries:
        raise DanceNetError("no songs given: name audio files, folders of them, or a list (.txt or .csv)")
    return [CatalogSong(label, path, safe_stem(path, "song"), settings) for label, path, settings in entries]


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DanceNetError(f"song list not found: {path} (check the path)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise DanceNetError(f"cannot read the song list {path}: {first_line(e)}") from e


def _read_list(path: Path) -> list[tuple[str, Path, dict[str, Any]]]:
    lines = (line.strip() for line in _read_text(path).splitlines())
    return [_entry(path, line, {}) for line in lines if line and not line.startswith("#")]


def _entry(listing: Path, song: str, settings: dict[str, Any]) -> tuple[str, Path, dict[str, Any]]:
    """A song named in a list, relative to the list's folder."""
    path = listing.parent / Path(song).expanduser()
    return str(path), path, settings


def _columns() -> dict[str, tuple[str, Any]]:
    """CSV column -> (request field, Option): the option's flag without dashes (`root-motion`, `start`), the
    field's name (`root_motion`, `start_s`) and `footfix` for `--no-footfix`."""
    columns = {}
    for name, _default, o in options():
        if o.flag is None:
            continue
        for column in {name, o.flag.lstrip("-").removeprefix("no-"), name.removesuffix("_s")}:
            columns[column] = (name, o)
            columns[column.replace("_", "-")] = (name, o)
    return columns


def _read_csv(path: Path) -> list[tuple[str, Path, dict[str, Any]]]:
    rows = list(csv.reader(io.StringIO(_read_text(path))))
    if not rows:
        raise DanceNetError(f"{path} is empty: give a header row with a 'song' column")
    header = [h.strip().lower() for h in rows[0]]
    columns = _columns()
    if "song" not in header:
        raise DanceNetError(f"{path} has no 'song' column: its first row names the columns (song, style, ...)")
    unknown = [h for h in header if h != "song" and h not in columns]
    if unknown:
        raise DanceNetError(f"{path}: unknown column '{unknown[0]}'; the columns are song and "
                            f"{', '.join(sorted({n for n in columns if '_' not in n}))}")
    entries = []
    for number, row in enumerate(rows[1:], 2):
        cells = {h: c.strip() for h, c in zip(header, row, strict=False)}
        if not cells.get("song"):
            if any(cells.values()):
                raise DanceNetError(f"{path} line {number}: no song named")
            continue
        settings = {}
        for column, text in cells.items():
            if column != "song" and text:
                name, option = columns[column]
                settings[name] = _value(path, number, column, text, option.kind)
        entries.append(_entry(path, cells["song"], settings))
    return entries


def _value(path: Path, number: int, column: str, text: str, kind: type) -> Any:
    """A CSV cell as its setting's type; a folder or file is relative to the CSV's folder."""
    if kind is bool:
        if text.lower() not in {"true", "false", "yes", "no", "1", "0", "on", "off"}:
            raise DanceNetError(f"{path} line {number}: {column} is yes or no, got '{text}'")
        return text.lower() in {"true", "yes", "1", "on"}
    if column in ("library", "weights"):
        resolved = path.parent / Path(text).expanduser()
        return resolved if kind is Path else str(resolved)
    try:
        return kind(float(text)) if kind is int and float(text).is_integer() else kind(text)
    except ValueError:
        raise DanceNetError(f"{path} line {number}: {column} must be a {'whole ' if kind is int else ''}number, "
                            f"got '{text}'") from None


# ---------------------------------------------------------------------------------------- requests and records


def request_id(song: CatalogSong, task: SongTask) -> str:
    """A hash of what makes the song's files: its bytes, its settings, the weights' bytes, the formats asked for
    and this version of the package. Raises DanceNetError when the song cannot be read."""
    check_song_path(song.path)
    settings = task.settings(song)
    h = hashlib.sha256()
    h.update(_digest(str(song.path)).encode())
    described = {"settings": settings, "outputs": task.outputs_key(), "weights": weights_identity(settings),
                 "version": __version__}
    h.update(json.dumps(described, sort_keys=True, default=str).encode())
    return h.hexdigest()[:40]


def weights_identity(settings: dict[str, Any]) -> list[str]:
    """Digests of the files a request may read to dance: the shipped weights and library, and the weights file
    and library folder it names (a missing one counts as missing: its engine says so when the song runs)."""
    files = sorted(WEIGHTS_DIR.glob("*.npz"))
    if settings.get("weights"):
        files.append(Path(settings["weights"]))
    if settings.get("library"):
        folder = Path(settings["library"])
        files += sorted(p for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else [folder]
    return [_digest(str(p)) for p in files]


def _digest(path: str) -> str:
    """sha256 of a file's bytes, remembered while its size and time stay the same."""
    try:
        st = os.stat(path)
    except OSError:
        return f"missing:{path}"
    return _cached_digest(path, st.st_size, st.st_mtime_ns)


@cache
def _cached_digest(path: str, _size: int, _mtime_ns: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _record(out: Path, folder: str) -> dict[str, Any] | None:
    try:
        record = json.loads((out / RECORDS / f"{folder}.json").read_text(encoding="utf-8"))
        return record if isinstance(record, dict) else None
    except (OSError, ValueError):
        return None


def _write_record(out: Path, song: CatalogSong, rid: str, row: dict[str, Any] | None) -> None:
    """The song's record: begun (no row: its files are being made) or complete (the row it ended with)."""
    record: dict[str, Any] = {"song": _identity(song), "request_id": rid, "complete": row is not None}
    if row is not None:
        record |= {"files": row["files"], "kept": {k: row.get(k) for k in KEPT}}
    (out / RECORDS).mkdir(exist_ok=True)
    write_text(out / RECORDS / f"{song.folder}.json", json.dumps(record, indent=1) + "\n")


def _identity(song: CatalogSong) -> str:
    return os.path.abspath(song.label)


def finished(out: Path, song: CatalogSong, rid: str) -> dict[str, Any] | None:
    """The kept fields of the song if its folder holds all its files for request `rid`, else None."""
    record = _record(out, song.folder)
    try:
        if record["complete"] and record["request_id"] == rid and \
                all((out / song.folder / name).is_file() for name in record["files"]):
            return dict(record["kept"])
    except (TypeError, KeyError):
        pass
    return None


def assign_folders(out: Path, songs: list[CatalogSong]) -> list[CatalogSong]:
    """Each song's folder: its name, else `_2`, `_3`...: the first that no earlier song of the list took and
    that is free (missing, or empty) or this song's (its record says so). A folder of the user's, or another
    song's, is never written into, and the same list in the same folder gives each song the same folder."""
    taken: set[str] = set()
    assigned = []
    for song in songs:
        name, k = song.folder, 1
        while name.casefold() in taken or not _ours(out, name, song):  # case-insensitive file systems too
            k += 1
            name = f"{song.folder}_{k}"
        taken.add(name.casefold())
        assigned.append(replace(song, folder=name))
    return assigned


def _ours(out: Path, name: str, song: CatalogSong) -> bool:
    folder = out / name
    if not os.path.lexists(folder):
        return True
    record = _record(out, name)
    if record is not None:
        return record.get("song") == _identity(song)
    return folder.is_dir() and not folder.is_symlink() and not any(folder.iterdir())


def dance_song(task: SongTask, song: CatalogSong, out: Path, rid: str) -> dict[str, Any]:
    """Run `task` on one song into its folder, whatever happens: the row of the status table for it. Its record
    says it begun before the first file, and complete after the last."""
    t0 = time.perf_counter()
    row: dict[str, Any] = {}
    folder = out / song.folder
    try:
        folder.mkdir(parents=True, exist_ok=True)
        remove_leftovers(folder)
        _write_record(out, song, rid, None)
        row = task(song, folder)
        _write_record(out, song, rid, row)
        row["status"] = "done"
    except DanceNetError as e:
        row = {"status": "failed", "error": str(e)}
    except Exception as e:  # a bug or an unforeseen file: this song's line, and the others go on
        row = {"status": "failed", "error": f"{type(e).__name__}: {first_line(e)}"}
    if row["status"] == "failed":
        with suppress(OSError):
            folder.rmdir()  # a folder left empty
    row["seconds"] = round(time.perf_counter() - t0, 2)
    row["peak_memory_mb"] = peak_memory_mb()
    return row


def peak_memory_mb() -> float | None:
    """This process' peak resident memory (None where the system does not say)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (2**20 if sys.platform == "darwin" else 2**10), 1)  # bytes on macOS, KiB elsewhere


# ---------------------------------------------------------------------------------------------- the status table


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
        write_text(self.out / "batch.json", json.dumps({"counts": self.counts(), "songs": table}, indent=1) + "\n")
        text = io.StringIO()
        writer = csv.DictWriter(text, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows({c: "" if v is None else v for c, v in row.items()} for row in table)
        write_text(self.out / "batch.csv", text.getvalue())


# -------------------------------------------------------------------------------------------------- the runner


Report = Callable[[CatalogSong, dict[str, Any]], None]


def run_catalog(songs: list[CatalogSong], out: Path, task: SongTask, *, where: Where = "local", jobs: int = 1,
                address: str | None = None, force: bool = False, report: Report | None = None) -> Status:
    """Dance every song of the catalog into `out`/<folder>, skipping those already done for the same request
    (unless `force`), and return the status table (also written to `out`). `report` hears of each song as it
    ends, skipped ones first."""
    if where == "ray":  # a missing Ray, or a cluster that does not answer, is said before anything is written
        ray_module()
        _check_reachable(address or os.environ.get("RAY_ADDRESS"))
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
    for i, song in enumerate(songs):
        try:
            rid = request_id(song, task)
        except DanceNetError as e:
            plan.append((i, song, "", {"status": "failed", "error": str(e)}))
            continue
        kept = None if force else finished(out, song, rid)
        if kept is not None:
            status.set(i, {**kept, "status": "skipped"})
            tell(song, status.rows[i])
        else:
            plan.append((i, song, rid, None))
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
            _run_local(todo, task, out, jobs, ended)
        else:
            _run_ray(todo, task, out, jobs, address, ended)
        return status
    finally:
        status.write()


def _run_local(todo: list, task: SongTask, out: Path, jobs: int,
               ended: Callable[[int, dict[str, Any]], None]) -> None:
    """Up to `jobs` worker processes (spawned: the same start on every platform, and Blender's `bpy`, which
    `--fbx` loads, is not safe to fork), each given one song at a time; one that dies is replaced and its song
    reported. However this ends (Ctrl-C, SIGTERM), the workers are stopped and their unfinished files removed."""
    context = mp.get_context("spawn")
    queue = deque(todo)
    busy: dict[Connection, tuple[mp.process.BaseProcess, tuple | None]] = {}

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
                    ended(item[0], {"status": "failed", "error": _death(process.exitcode)})
                    if queue:
                        start()
                    continue
                ended(i, row)
                give(conn, process)
    finally:
        _stop(out, busy, ended)


def _stop(out: Path, busy: dict[Connection, tuple[mp.process.BaseProcess, tuple]],
          ended: Callable[[int, dict[str, Any]], None]) -> None:
    """Stop the workers still dancing (Ctrl-C, SIGTERM, an error here) at once, and remove their unfinished
    files: each temporary name says its process, now gone (`atomic.remove_leftovers`). Killed, not asked: a
    signal that Python turns into an exception can land where it is lost (a C library's callback), and the
    files are removed here either way. A song a worker finished before the stop, its row still in the pipe
    (workers that start together end their first songs together), is reported done, as the next run finds it."""
    for process, _item in busy.values():
        process.kill()
    for conn, (process, (_i, song, _rid)) in busy.items():
        process.join()
        with suppress(EOFError, OSError):  # nothing sent, or a row cut off by the kill
            if conn.poll():
                ended(*conn.recv())
        remove_leftovers(out / song.folder)
    remove_leftovers(out / RECORDS)


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


# ----------------------------------------------------------------------------------------------------------- Ray


def ray_module() -> Any:
    """Ray, or a one-line error saying how to install it."""
    try:
        import ray
    except ImportError:
        raise DanceNetError('--cluster ray needs Ray: pip install "dancenet[cluster]" (or pip install ray)') from None
    return ray


def _run_ray(todo: list, task: SongTask, out: Path, jobs: int, address: str | None,
             ended: Callable[[int, dict[str, Any]], None]) -> None:
    """Each song a Ray task: the driver reads the song and sends its bytes, the task dances a copy on its node
    and sends the files back, and the driver writes them (the nodes need the package, not a shared folder).
    Connects to `address` (or `$RAY_ADDRESS`), else to a cluster running on this machine, else starts Ray here
    with `jobs` CPUs; a Ray session already started in this process is used as it is."""
    ray = ray_module()
    started = not ray.is_initialized()
    if started:
        local = address is None and not os.environ.get("RAY_ADDRESS")
        settings = {"address": address, "include_dashboard": False, "logging_level": "ERROR"}
        try:
            try:
                ray.init(**settings, num_cpus=max(1, jobs) if local else None)
            except ValueError as e:  # a cluster `ray start` left running here, which Ray joins (its CPUs, not ours)
                if not local or "existing cluster" not in str(e):
                    raise
                ray.init(**settings)
        except (ConnectionError, RuntimeError, ValueError) as e:
            where = address or os.environ.get("RAY_ADDRESS") or "this machine"
            raise DanceNetError(f"cannot start or reach Ray at {where}: {first_line(e)}; start the cluster with "
                                "`ray start --head` (docs/catalog.md) or check --address") from e
    # Songs side by side, the analysis of each in its task's process alone.
    env = {"DANCENET_WORKERS": "1"}
    remote = ray.remote(_ray_song).options(num_cpus=1, max_retries=1, runtime_env={"env_vars": env})
    queue = deque(todo)
    pending: dict[Any, tuple] = {}
    in_flight = 2 * max(1, int(ray.cluster_resources().get("CPU", 1)))  # bounds the songs held in memory
    try:
        while queue or pending:
            while queue and len(pending) < in_flight:
                item = queue.popleft()
                i, song, rid = item
                try:
                    data = song.path.read_bytes()
                except OSError as e:
                    ended(i, {"status": "failed", "error": f"cannot read {song.label}: {e.strerror or e}"})
                    continue
                pending[remote.remote(task, song, data, rid)] = item
            if not pending:
                continue
            (ref,), _rest = ray.wait(list(pending), num_returns=1)
            i, song, rid = pending.pop(ref)
            try:
                row, files = ray.get(ref)
                if row["status"] == "done":
                    _commit(out, song, files, rid, row)
            except ray.exceptions.RayError as e:
                row = {"status": "failed", "error": f"the Ray task failed: {first_line(e)}"}
            except DanceNetError as e:
                row = {"status": "failed", "error": str(e)}
            ended(i, row)
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def _check_reachable(address: str | None) -> None:
    """A cluster's `host:port` answers, or a one-line error in seconds (Ray itself retries for minutes)."""
    host, _colon, port = (address or "").rpartition("://")[2].rpartition(":")
    if not host or not port.isdigit():  # "auto", or none: Ray finds or starts its own
        return
    try:
        socket.create_connection((host, int(port)), timeout=10).close()
    except OSError as e:
        raise DanceNetError(f"no Ray cluster answers at {address} ({e.strerror or e}); start its head with "
                            "`ray start --head` (docs/catalog.md) or check --address") from None


def _ray_song(task: SongTask, song: CatalogSong, data: bytes, rid: str) -> tuple[dict[str, Any], dict[str, bytes]]:
    """On a Ray node: the song's row and files, danced from its bytes in a scratch folder."""
    with tempfile.TemporaryDirectory(prefix="dancenet-batch-") as scratch:
        path = Path(scratch) / "song" / song.path.name
        path.parent.mkdir()
        path.write_bytes(data)
        row = dance_song(task, replace(song, path=path), Path(scratch) / "out", rid)
        folder = Path(scratch) / "out" / song.folder
        files = {name: (folder / name).read_bytes() for name in row.get("files", [])}
    return row, files


def _commit(out: Path, song: CatalogSong, files: dict[str, bytes], rid: str, row: dict[str, Any]) -> None:
    """A cluster song's files written into its folder on this machine, together, between its records."""
    folder = out / song.folder
    folder.mkdir(parents=True, exist_ok=True)
    remove_leftovers(folder)
    _write_record(out, song, rid, None)
    with claimed_outputs([folder / name for name in files], overwrite=True) as temp:
        for name, data in files.items():
            temp[folder / name].write_bytes(data)
    _write_record(out, song, rid, row)

