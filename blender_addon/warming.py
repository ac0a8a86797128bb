"""The add-on's warm-up thread (the first Generate Dance's imports and weights, and the numba kernels, compiled
by a process of its own meanwhile: dancenet_core/warmup.py; with the preference Commercial Use only, what the
commercial mode runs alone) and the lock a Generate Dance shares with it.

Why a lock: numba's first compile of a kernel and the loading of madmom's compiled networks are not safe to run
on two threads at once. Each warm-up step and each generation hold `LOCK`, so a click during the warm-up waits
for its current step and then finds that work done; a generation also stops the compiling process while it runs
(`generating`).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

LOCK = threading.Lock()
_stop = threading.Event()
_thread: threading.Thread | None = None


def _warm_up(stop: threading.Event, commercial: bool) -> None:
    """Never touches bpy, so disabling the add-on meanwhile only stops it early. Not a daemon thread: one frozen
    mid-import or mid-compile when Python shuts down can hang the shutdown, so Python waits for it instead, and
    the thread stops after its current step once the main thread has ended (bpy as a Python module: the script
    is done; Blender's own main thread runs until it quits, and disables its add-ons then)."""

    def cancelled() -> bool:
        return stop.is_set() or not threading.main_thread().is_alive()

    try:
        from dancenet_core.warmup import warm_up

        warm_up(cancelled, LOCK, commercial=commercial)
    except Exception as e:  # a failed warm-up costs only speed; a Generate Dance reports the fault itself
        if not cancelled():  # an import cut short by Python's shutdown is no fault
            print(f"DanceNet: warm-up stopped: {e}")


@contextlib.contextmanager
def generating() -> Iterator[None]:
    """What a generation holds while it runs: the warm-up's compiling process stopped once it has written the
    music analysis' kernels (which the click waits for; the sampler's kernel runs its numpy twin meanwhile), so
    that the click has the CPU, and then `LOCK`, so that it never runs beside a warm-up step. Stopped first: the
    wait for a warm-up step under way goes faster without it too."""
    from dancenet_core.warmup import paused

    with paused(), LOCK:
        yield


def start(commercial: bool) -> None:
    """Warm up on a thread of its own (each registration has its own stop signal); `commercial` (the add-on's
    preference Commercial Use only): only what a dance in Commercial Use runs, nothing with a non-commercial
    licence opened. The kernels are deferred first (dancenet_core.jit): until the warm-up has them compiled, a
    click waits for the music analysis' kernels from its compiling process and runs the others' numpy twins
    (dancenet_core/warmup.py)."""
    global _stop, _thread
    from dancenet_core import jit

    jit.defer()
    _stop = threading.Event()
    _thread = threading.Thread(target=_warm_up, args=(_stop, commercial), name="dancenet-warm-up")
    _thread.start()


def stop() -> None:
    """Ask the warm-up to stop after its current step (without waiting: disabling must not freeze Blender)."""
    _stop.set()


def wait(timeout: float | None = None) -> None:
    """Until the warm-up has ended (tests: nothing of it runs beside them)."""
    if _thread is not None:
        _thread.join(timeout)
