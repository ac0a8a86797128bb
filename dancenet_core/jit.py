"""The numba kernels' numpy twins, and which of the two runs.

Compiling the kernels (the music networks' loop, the beat tracker's decode, the sampler) takes seconds of CPU
from cold; a Blender add-on clicked right after it is installed would spend most of its first Generate Dance
waiting for it (15-22 s for a 12-s strip, compiled on the click). Each kernel therefore has a numpy twin that does the
same arithmetic in the same order, so it gives the same numbers bit for bit (tests/test_jit.py compares them):
slower per frame, but it needs no compile, and a short song is short. The command line compiles on first use
as it always did; the add-on calls `defer()`, so that a kernel runs compiled only once its warm-up (a process
of its own, dancenet_core/warmup.py) has put it in numba's cache and this process has loaded it.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

_deferred = False
_cached: set[Any] = set()  # kernels another process has written to numba's on-disk cache: a call loads them
_coming: set[Any] = set()  # kernels another process is compiling now, which a call waits for (`expect`)
_arrived = threading.Condition()  # guards the two sets; told when either changes
WAIT_S = 30.0  # the longest a call waits for a coming kernel (a process that hangs) before running its twin
_here = threading.local()  # .compiling: this thread may compile (or load) kernels though they are deferred


def defer() -> None:
    """From now on, a kernel that this process has not compiled or loaded yet runs its numpy twin instead."""
    global _deferred
    _deferred = True


def may_compile() -> bool:
    """Whether a kernel not yet compiled is compiled (or loaded from numba's cache) when it is called here."""
    return not _deferred or getattr(_here, "compiling", False)


@contextlib.contextmanager
def compiling() -> Iterator[None]:
    """On this thread, compile or load kernels though they are deferred (the warm-up loading them)."""
    _here.compiling = True
    try:
        yield
    finally:
        _here.compiling = False


def expect(*kernels: Any) -> None:
    """Another process is compiling these now: a call waits for them rather than running their twins (where
    the compile is quicker than the twin: the music networks' twins take ~4 s a minute of song, their compile
    ~2 s, and the compiling process started before the click)."""
    with _arrived:
        _coming.update(kernels)
        _arrived.notify_all()


def expect_none() -> None:
    """No kernel is coming any more (the compiling process has ended, however): calls waiting run twins."""
    with _arrived:
        _coming.clear()
        _arrived.notify_all()


def coming() -> bool:
    """Whether a call may wait for a kernel another process is compiling."""
    with _arrived:
        return bool(_coming)


def mark_cached(*kernels: Any) -> None:
    """These kernels are in numba's on-disk cache now (the warm-up's compiling process wrote them)."""
    with _arrived:
        _cached.update(kernels)
        _coming.difference_update(kernels)
        _arrived.notify_all()


def pick(kernel: Any, twin: Any) -> Any:
    """`kernel` (a numba dispatcher) where it is compiled in this process, in numba's cache or may be compiled
    now, or once another process has compiled it where one is compiling it (`expect`), else `twin`."""
    if kernel.signatures or may_compile():
        return kernel
    with _arrived:
        _arrived.wait_for(lambda: kernel not in _coming, WAIT_S)
        return kernel if kernel in _cached else twin
