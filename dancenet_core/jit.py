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


def mark_cached(*kernels: Any) -> None:
    """These kernels are in numba's on-disk cache now (the warm-up's compiling process wrote them)."""
    _cached.update(kernels)


def pick(kernel: Any, twin: Any) -> Any:
    """`kernel` (a numba dispatcher) where it is compiled in this process, in numba's cache or may be compiled
    now, else `twin`."""
    return kernel if kernel.signatures or kernel in _cached or may_compile() else twin
