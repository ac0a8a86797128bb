"""Work on a worker thread (a generation, a library build; the thread never touches bpy, the main thread polls it),
and how an error reaches the user."""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from typing import Any

from dancenet_core.errors import DanceNetError, GenerationCancelled
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
            with warming.generating():  # never beside a warm-up step nor its compile (warming.py)
                self.result = self._work(self._progress, self._cancel.is_set)
        except Exception as e:  # reported on the main thread; a cancelled job's error is dropped
            self.error = e

    def poll(self) -> None:
        """The operator's tick on the main thread (a worker's job has nothing to do there; `Staged` does)."""

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


# A step of a `Staged` job: (what the status bar says, the step; it runs on the main thread and may use bpy).
Step = tuple[str, Callable[[], Any]]


class Staged(Job):
    """Steps that need bpy (sampling rigs in Blender for a library), one per `poll` on the main thread, so the
    status bar moves and Esc is heard between them; then the work their results make (`then`) on a worker thread.
    `run_now` does it all on the calling thread (scripts, background mode)."""

    def __init__(self, steps: list[Step], then: Callable[[list[Any]], Work], name: str) -> None:
        super().__init__(self._after_steps, name)
        self._steps, self._then, self._results = steps, then, []
        self._next: Work | None = None

    def _after_steps(self, progress: StageProgress, should_cancel: Callable[[], bool]) -> Any:
        assert self._next is not None
        return self._next(progress, should_cancel)

    def start(self) -> None:
        """The steps start at the first `poll`."""

    def poll(self) -> None:
        if self._thread.ident is not None or self.error is not None:  # the work started, or a step failed
            return
        if self._cancel.is_set():
            self.error = GenerationCancelled()
        elif len(self._results) < len(self._steps):
            stage, step = self._steps[len(self._results)]
            self._progress(stage, len(self._results) / max(len(self._steps), 1))
            try:
                self._results.append(step())
            except Exception as e:  # reported on the main thread as a worker's error is
                self.error = e
        else:
            self._next = self._then(self._results)
            self._thread.start()

    @property
    def done(self) -> bool:
        return self.error is not None or (self._thread.ident is not None and not self._thread.is_alive())

    def join(self, timeout: float | None = None) -> None:
        """The steps (here, on the calling thread), then the work's thread."""
        while self._thread.ident is None and self.error is None:
            self.poll()
        if self._thread.ident is not None:
            self._thread.join(timeout)

    def run_now(self) -> Any:
        """Every step, then the work, on the calling thread."""
        results = [step() for _stage, step in self._steps]
        return self._then(results)(lambda _stage, _fraction: None, lambda: False)
