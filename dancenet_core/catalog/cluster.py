"""A catalog's songs danced as tasks on a Ray cluster: the driver (this process) reads each song and sends its
bytes, the task dances a copy on its node and sends the files back, and the driver writes them, so the nodes
share no folder."""

from __future__ import annotations

import os
import socket
import tempfile
from collections import deque
from dataclasses import replace
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ..atomic import remove_leftovers, write_error
from ..errors import DanceNetError, first_line
from ..outputs import claimed_outputs
from .dance import dance_song
from .local import Ended, Item
from .records import write_record
from .songs import CatalogSong, SongTask


def ray_module() -> Any:
    """Ray, or a one-line error saying how to install it."""
    try:
        import ray
    except ImportError:
        raise DanceNetError('--cluster ray needs Ray: pip install "dancenet[cluster]" (or pip install ray)') from None
    return ray


def run_ray(todo: list[Item], task: SongTask, out: Path, jobs: int, address: str | None, ended: Ended) -> None:
    """Each song a Ray task, the files it sends back written here (`_commit`). Connects to `address` (or
    `$RAY_ADDRESS`), else to a cluster running on this machine, else starts Ray here with `jobs` CPUs; a Ray
    session already started in this process is used as it is."""
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
    pending: dict[Any, Item] = {}
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
            except OSError as e:  # as a song that cannot be written here fails on its own in a local worker
                row = {"status": "failed", "error": str(write_error(Path(e.filename or out / song.folder), e))}
            ended(i, row)
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def check_reachable(address: str | None) -> None:
    """A cluster's `host:port` answers, or a one-line error in seconds (Ray itself retries for minutes)."""
    text = address or ""
    try:
        parts = urlsplit(text if "://" in text else f"//{text}")
        host, port = parts.hostname, parts.port
    except ValueError:  # a port that is not a number: Ray's own error says so
        return
    if not host or port is None:  # "auto", or none: Ray finds or starts its own
        return
    try:
        socket.create_connection((host, port), timeout=10).close()
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
    write_record(out, song, rid, None)
    with claimed_outputs([folder / name for name in files], overwrite=True) as temp:
        for name, data in files.items():
            temp[folder / name].write_bytes(data)
    write_record(out, song, rid, row)
