"""Everything a first Generate Dance waits for that is not the song itself: the imports (madmom, scipy), the
numba kernels (compiled, or read from numba's on-disk cache) and the shipped weights. The Blender add-on runs
`warm_up` on a thread of its own when it is enabled, so that a click later does not spend its time on them.

Where kernels are deferred (dancenet_core.jit: the add-on), a Python process of its own, started first,
compiles them into numba's cache while this one imports and loads the rest; each kernel is used from numba's
cache as soon as that process has written it (a call then only loads it). Once the process is done, the
kernels are loaded here, a step at a time (compiled here if the process failed).

A click meanwhile waits for the music analysis' kernels from that process rather than running their numpy
twins (the same numbers, but the twins take longer on a minute of song than that process takes to compile
both, and it started when the add-on was enabled), and runs the sampler's twin (a fraction of a second for a
short dance). While a Generate Dance runs, that process is stopped once it has written the analysis' kernels
(`paused`) and continued after: on a machine with few cores its compile would take the CPU from the click. The
measurements behind these choices: docs/experiments.md, "The first click on a Rigify rig".

The kernels are compiled by running the real code on a few seconds of noise and a few frames of silence, so
they get the argument types a real run gives them; nothing is written to the music cache. The heavy modules
are imported inside the steps, so that the compiling process starts before this one imports them.

In the commercial mode (the add-on's preference Commercial Use only) none of that runs: the weights and the
style classifier are trained on Dance with Melody, the default analysis runs madmom's networks (CC BY-NC-SA
model files), and the compiling process's sampler step loads the weights. What a dance in that mode runs has no
kernel (the weight-free analysis and the library engine are numpy and scipy; the networks' loop and the beat
decode open no model file but only the default analysis runs them), so nothing is compiled: the generator's
imports are loaded and the weight-free analysis is run on the noise (`_weightfree`)."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from typing import IO, Any, NamedTuple

import numpy as np

from . import jit

WARM_AUDIO_S = 3  # one block of the analysis: both networks, chroma and the beat tracker's decode
WARM_FRAMES = 8  # the sampler's kernel is the same for any length


def _noise(sample_rate: int) -> np.ndarray:
    """`WARM_AUDIO_S` of quiet noise, the song the analyses warm up on."""
    return (0.1 * np.random.default_rng(0).standard_normal(WARM_AUDIO_S * sample_rate)).astype(np.float32)


def _analysis() -> None:
    """The analysis' imports, madmom's networks, the onset and beat networks' loop, the downbeat tracker's
    decode, chroma and mel."""
    from pathlib import Path

    from .music.audio import MADMOM_SAMPLE_RATE, Audio
    from .music.features import analyze_audio

    analyze_audio(Audio(_noise(MADMOM_SAMPLE_RATE), MADMOM_SAMPLE_RATE, MADMOM_SAMPLE_RATE, 1, Path("warm-up")),
                  workers=1)


def _dance() -> None:
    """The weights (kept by their loaders' caches for the real run), the sampler's kernel, the foot clean-up."""
    from .constants import DEFAULT_TEMPERATURE
    from .engines.dancenet import clean_feet, load_bundle, sample_dance
    from .engines.styles import load_style_model
    from .music.features import N_FEATURES
    from .runtime.sampler import Sampling, music_conditioning

    bundle = load_bundle()
    load_style_model()
    cond = music_conditioning(bundle.model, np.zeros((WARM_FRAMES, N_FEATURES), np.float32), 0)
    first = bundle.normalizer.normalize(bundle.start_frames[bundle.styles[0]][:1])
    takes = sample_dance(bundle, cond, first, Sampling(DEFAULT_TEMPERATURE, np.random.default_rng(0)))
    clean_feet(bundle, takes[0])


def _weightfree() -> None:
    """What a Generate Dance in the commercial mode loads first: the generator, the library engine and the
    weight-free analysis (licence.NON_COMMERCIAL_FILES: none of them is opened)."""
    import importlib
    from pathlib import Path

    from .engines import get_engine
    from .music.audio import MADMOM_SAMPLE_RATE, Audio
    from .music.weightfree import analyze_audio_weightfree

    importlib.import_module(f"{__package__}.generate")
    get_engine("library")
    analyze_audio_weightfree(Audio(_noise(MADMOM_SAMPLE_RATE), MADMOM_SAMPLE_RATE, MADMOM_SAMPLE_RATE, 1,
                                   Path("warm-up")))


def _kernels() -> dict[str, tuple[Callable[[], None], tuple[Any, ...]]]:
    """Each kernel by name: the step that compiles or loads it, and its numba dispatchers."""
    from .music import madmom_dbn, madmom_nets
    from .runtime import sampler

    return {
        "networks": (madmom_nets.load_compiled, madmom_nets.KERNELS),
        "beat decode": (madmom_dbn.load_compiled, madmom_dbn.KERNELS),
        "sampler": (_dance, sampler.KERNELS),
    }


WAITED = ("networks", "beat decode")  # the kernels a click waits for (above), compiled first


def _all_loaded() -> bool:
    """Whether this process has every kernel already (a warm-up ran here before: the add-on enabled again), so
    that no process is started to compile them. Looked up without importing the kernels' modules, which a first
    warm-up imports only once its compiling process has started."""
    names = ("music.madmom_nets", "music.madmom_dbn", "runtime.sampler")
    modules = [sys.modules.get(f"{__package__}.{name}") for name in names]
    return all(m is not None and all(k.signatures for k in m.KERNELS) for m in modules)


def compile_kernels() -> None:
    """Compile every kernel into numba's on-disk cache, printing each one's name once it is there (what the
    process `warm_up` starts runs)."""
    for name, (step, _) in _kernels().items():
        step()
        print(name, flush=True)


# Not niced where a click can stop it (a click waits for its first kernels, which a niced process on a busy
# machine would be slow to write); at below-normal priority elsewhere (its creation flags).
_CHILD = ("import sys; sys.path[:0] = sys.argv[1:]; "
          "from dancenet_core.warmup import compile_kernels; compile_kernels()")
POLL_S = 0.2  # how often the wait for that process looks at `cancelled`


class _Compiling(NamedTuple):
    """The compiling process and the file its stderr goes to: a file, not a pipe, since a pipe read only once
    the process ends would fill with numba's warnings and block it for ever."""

    process: subprocess.Popen
    errors: IO[bytes]


# POSIX's stop and continue; where there are none (Windows) the process runs on beside a click, at below-normal
# priority (its creation flags), which the scheduler puts after the click's thread: correct, only slower.
_STOP, _CONT = getattr(signal, "SIGSTOP", None), getattr(signal, "SIGCONT", None)
_pause = threading.Lock()  # guards the two below
_running: subprocess.Popen | None = None  # the compiling process until it has been waited for
_pausers = 0  # generations under way that asked for it to be stopped


def _steer() -> None:
    """Stop the compiling process while a generation runs and no kernel it waits for is still coming; else let
    it run (Popen.send_signal skips a process already waited for, so a process id used again by another process
    is never signalled; a stop or a continue sent twice does nothing more). Caller holds `_pause`."""
    sig = _STOP if _pausers and not jit.coming() else _CONT
    if _running is not None and sig is not None:
        with contextlib.suppress(ProcessLookupError):  # ended meanwhile, not yet waited for
            _running.send_signal(sig)


@contextlib.contextmanager
def paused() -> Iterator[None]:
    """The compiling process stopped while the body runs (a Generate Dance: it gets the CPU that process would
    take) once it has written the kernels the body may wait for, continued after, however the body ends.
    Nested or concurrent bodies continue it once the last ends; a process started meanwhile is stopped too."""
    global _pausers
    with _pause:
        _pausers += 1
        _steer()
    try:
        yield
    finally:
        with _pause:
            _pausers -= 1
            _steer()


def _track(child: subprocess.Popen | None) -> None:
    """Make `child` the process `paused` stops (None: none any more), stopped at once if a pause is under way
    and no kernel is coming from it."""
    global _running
    with _pause:
        _running = child
        _steer()


def _compile_elsewhere() -> _Compiling:
    """This interpreter (in Blender, Blender's own Python) on this process's import path, isolated from the
    user's Python settings but for this process's bytecode policy (-I drops PYTHONDONTWRITEBYTECODE, and an
    extension's folder must stay as installed when its user asked for no .pyc); numba's cache folder comes with
    the environment. A thread marks each kernel cached (dancenet_core.jit) as the process names it."""
    no_pyc = ["-B"] if sys.dont_write_bytecode else []
    errors = tempfile.TemporaryFile()
    child = subprocess.Popen([sys.executable, "-I", *no_pyc, "-c", _CHILD, *sys.path], stdin=subprocess.DEVNULL,
                             stdout=subprocess.PIPE, stderr=errors, text=True,
                             creationflags=getattr(subprocess, "BELOW_NORMAL_PRIORITY_CLASS", 0))  # fmt: skip
    kernels = _kernels()
    jit.expect(*(kernel for name in WAITED for kernel in kernels[name][1]))
    _track(child)
    threading.Thread(target=_mark_cached, args=(child.stdout, kernels), name="dancenet-compiled", daemon=True).start()
    return _Compiling(child, errors)


def _mark_cached(names: IO[str], kernels: dict[str, tuple[Callable[[], None], tuple[Any, ...]]]) -> None:
    """Mark each of `kernels` cached as the process names it (and stop the process if a generation waits no more
    for it); once it has ended, however, nothing is coming from it."""
    try:
        for line in names:
            if line.strip() in kernels:
                jit.mark_cached(*kernels[line.strip()][1])
                with _pause:
                    _steer()
    finally:
        jit.expect_none()


def _finished(compiling: _Compiling, cancelled: Callable[[], bool]) -> bool:
    """Wait for the compiling process; False (and the process ended) if cancelled meanwhile (a kill ends a
    paused process too)."""
    child = compiling.process
    with compiling.errors, contextlib.ExitStack() as untrack:
        untrack.callback(_track, None)
        while not cancelled():
            try:
                child.wait(timeout=POLL_S)
            except subprocess.TimeoutExpired:
                continue
            if child.returncode:
                compiling.errors.seek(0)
                lines = compiling.errors.read().decode(errors="replace").strip().splitlines()
                print(f"DanceNet: compiling the kernels apart failed ({(lines or ['?'])[-1]}); compiling them here")
            return True
        child.kill()
        child.wait()
        return False


def warm_up(cancelled: Callable[[], bool] = lambda: False, lock: AbstractContextManager | None = None, *,
            commercial: bool = False) -> None:
    """Load or compile what a Generate Dance needs, checking `cancelled` between steps (a compile cannot be
    stopped midway, so each kernel is a step of its own), each step holding `lock`: a caller that runs real
    generations on other threads holds the same lock around them, so the two never race. With the kernels
    deferred, another process compiles them meanwhile (see above). `commercial`: what a dance in the commercial
    mode needs, and nothing with a non-commercial licence (see above)."""
    held = lock or contextlib.nullcontext()
    if commercial:
        if not cancelled():
            with held:
                _weightfree()
        return
    child = _compile_elsewhere() if not (jit.may_compile() or _all_loaded()) else None
    if child is not None:
        try:
            if not cancelled():
                with held:
                    _dance()  # the weights, while the kernels compile (the sampler's twin on 8 frames)
        except BaseException:
            _finished(child, lambda: True)  # a failed step leaves no process unwaited, no stderr file open
            raise
        if not _finished(child, cancelled):
            return
    for step in (*(step for step, _ in _kernels().values()), _analysis):
        if cancelled():
            return
        with held, jit.compiling():
            step()
