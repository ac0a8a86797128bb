"""Where things live and how much to run at once, as the environment decides: the shipped weights, the one
cache folder (`$DANCENET_CACHE`, numba's compiled code inside it), the shared data folder (`$DANCENET_DATA`)
and worker processes (`$DANCENET_WORKERS`; they end with their parent). One home, so the command line, the add-on
and training never disagree."""

from __future__ import annotations

import ctypes
import functools
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, ParamSpec, TypeVar

if TYPE_CHECKING:
    from concurrent.futures import Executor

P = ParamSpec("P")
R = TypeVar("R")

# Shipped checkpoints, the song split and the model cards.
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"


def cache_root() -> Path:
    """`$DANCENET_CACHE` if set (the Blender add-on sets it to its extension's user folder), else `dancenet` in the
    user's cache folder; each cache is a folder inside it."""
    env = os.environ.get("DANCENET_CACHE")
    return Path(env).expanduser() if env else user_cache_dir() / "dancenet"


def user_cache_dir() -> Path:
    """Where the platform keeps a user's caches: %LOCALAPPDATA% on Windows, ~/Library/Caches on macOS,
    $XDG_CACHE_HOME (an absolute path) or ~/.cache elsewhere; never the install folder, which may be read-only."""
    if sys.platform == "win32":
        local = os.environ.get("LOCALAPPDATA")
        return Path(local) if local else Path.home() / "AppData" / "Local"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    return Path(xdg) if os.path.isabs(xdg) else Path.home() / ".cache"


def default_data_dir() -> Path:
    """`$DANCENET_DATA`, else the shared data folder next to the repository."""
    env = os.environ.get("DANCENET_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "data"


def default_workers() -> int:
    """$DANCENET_WORKERS, else 2 (the networks are single-threaded); 1 inside Blender, whose process (GUI
    threads, its own allocators) is not worth the risk of forking."""
    env = os.environ.get("DANCENET_WORKERS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return 1 if "bpy" in sys.modules else min(2, os.cpu_count() or 1)


def one_blas_thread(fn: Callable[P, R]) -> Callable[P, R]:
    """`fn` with numpy's and scipy's BLAS on one thread: a matrix product's sums then run in one order, so a
    song's analysis and its dance are the same bytes whatever the machine's cores, `OMP_NUM_THREADS` or process
    (two threads moved the music features by up to 2e-4, and through the sampler the whole dance). Songs and
    blocks run side by side in processes instead (`default_workers`, `dancenet batch --jobs`)."""

    @functools.wraps(fn)
    def on_one_thread(*args: P.args, **kwargs: P.kwargs) -> R:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1, user_api="blas"):
            return fn(*args, **kwargs)

    return on_one_thread


def end_with_parent(parent: int) -> None:
    """First thing in a worker process: end it when its parent `parent` ends, however that ends (SIGKILL, a
    closed terminal's SIGHUP), so no worker, nor a pipe it holds open (ffmpeg waits on those), outlives its
    run. Linux: the kernel's parent-death signal; other POSIX systems: a thread that watches the parent."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(1, signal.SIGKILL, 0, 0, 0) == 0:  # PR_SET_PDEATHSIG
            if os.getppid() != parent:  # the parent was gone before the signal was armed
                os._exit(1)
            return
    if os.name == "posix":
        threading.Thread(target=_exit_with, args=(parent,), daemon=True, name="end-with-parent").start()


def _exit_with(parent: int) -> None:
    """Exit once this process' parent is no longer `parent` (an orphan is adopted by another process)."""
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(1)


def stop_pool(ex: Executor) -> None:
    """Stop a pool now (Ctrl-C, SIGTERM, SIGHUP, a failed block) and wait until it has: a running block can take
    a minute, the pool's exit would wait for it, and a worker whose parent died blocks forever. The queued
    blocks are dropped by the pool's own thread (shutdown's cancel_futures): cancelled from here, that thread
    could find one cancelled when it marks the queue failed after a worker is killed, and die with a traceback
    (InvalidStateError) before it ends the other workers. Python 3.11's pool has no public call to kill its
    workers; `_processes` is its pid -> Process map (shutdown forgets it, so it is read first)."""
    workers = list((getattr(ex, "_processes", None) or {}).values())
    manager = getattr(ex, "_executor_manager_thread", None)
    ex.shutdown(wait=False, cancel_futures=True)
    for proc in workers:
        proc.kill()
    for proc in workers:
        proc.join()
    if manager is not None:
        manager.join()
