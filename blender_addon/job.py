"""Work on a worker thread (a generation, a library build; the thread never touches bpy, the main thread polls it),
and how an error reaches the user."""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from typing import Any

from dancenet_core.errors import DanceNetError
from dancenet_core.progress import StageProgress
from dancenet_core.request import DanceRequest

from . import warming

Generator = Callable[..., Any]  # dancenet_core.generate.generate_dance or a stand-in with its signature
# What a job runs on its worker thread, given where to report progress and what says to stop: the result.
Work = Callable[[StageProgress, Callable[[], bool]], Any]


def error_message(error: BaseException, doing: str = "Generation") -> str:
    """One line for the user; unexpected errors also go to the console with their traceback."""
    if isinstance(error, DanceNetError):
        return str(error)
    traceback.print_exception(error)
    return f"{doing} failed: {type(error).__name__}: {error} (details in the system console)"


class Job:
    """Work on a worker thread (a generation, a library build). The thread never touches bpy; the main thread
    polls it."""

    def __init__(self, work: Work, name: str) -> None:
        self._work = work
        self._lock = threading.Lock()
        self._cancel = threading.Event()
        self._stage, self._fraction = "Starting", 0.0
        self.result: Any = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _progress(self, stage: str, fraction: float) -> None:
        with self._lock:
            self._stage, self._fraction = stage, min(max(float(fraction), 0.0), 1.0)

    def _run(self) -> None:
        try:
            with warming.LOCK:  # never beside a warm-up step (warming.py)
                self.result = self._work(self._progress, self._cancel.is_set)
        except Exception as e:  # reported on the main thread; a cancelled job's error is dropped
            self.error = e

    def progress(self) -> tuple[str, float]:
        with self._lock:
            return self._stage, self._fraction

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)


def generation(generator: Callable[[], Generator], request: DanceRequest) -> Job:
    """The generator run on `request`; the generator itself is fetched on the worker (its first import costs
    seconds, which must not freeze the UI)."""
    return Job(lambda progress, should_cancel: generator()(request, progress=progress, should_cancel=should_cancel),
               "dancenet-generate")
