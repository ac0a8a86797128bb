"""The warm-up the add-on runs when it is enabled compiles every kernel a Generate Dance runs,
with the types a real run gives them: a Generate Dance after it compiles nothing more."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.made_up import CountingChild

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
import sys
from dancenet_core.runtime import sampler
from dancenet_core.music import madmom_dbn, madmom_nets
from dancenet_core.warmup import warm_up

kernels = (madmom_nets._scan, madmom_dbn._viterbi, madmom_dbn._backtrack, sampler._generate)
warm_up(lambda: True)
print("CANCELLED", [len(k.signatures) for k in kernels])
warm_up()
print("WARM", [len(k.signatures) for k in kernels])
from dancenet_core.generate import generate_dance
from dancenet_core.request import DanceRequest
generate_dance(DanceRequest(sys.argv[1], end_s=4.0))
print("AFTER", [len(k.signatures) for k in kernels])
"""


def test_a_generate_after_the_warm_up_compiles_nothing(tmp_path: Path) -> None:
    """In a fresh process (a test before this one may have compiled them), music cache in a scratch folder."""
    env = os.environ | {"DANCENET_CACHE": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", PROBE, str(ROOT / "examples" / "example_song.ogg")], cwd=ROOT,
                         env=env, capture_output=True, text=True, check=True).stdout  # fmt: skip
    assert "CANCELLED [0, 0, 0, 0]" in out
    assert "WARM [1, 1, 1, 1]" in out
    assert "AFTER [1, 1, 1, 1]" in out

DEFERRED = """
import sys
from dancenet_core import jit
from dancenet_core.runtime import sampler
from dancenet_core.music import madmom_dbn, madmom_nets
from dancenet_core.warmup import warm_up
from dancenet_core.generate import generate_dance
from dancenet_core.request import DanceRequest

kernels = (madmom_nets._scan, madmom_dbn._viterbi, madmom_dbn._backtrack, sampler._generate)
jit.defer()
generate_dance(DanceRequest(sys.argv[1], end_s=4.0))
print("TWINS", [len(k.signatures) for k in kernels])
warm_up()
print("WARM", [len(k.signatures) for k in kernels], sorted(map(sampler.KERNELS.__contains__, jit._cached)))
"""


def test_deferred_kernels_are_compiled_apart(tmp_path: Path) -> None:
    """As in the add-on: a Generate Dance before the warm-up compiles nothing (the twins dance); the warm-up's
    own process compiles every kernel into numba's cache (each marked as it is written), and this one loads
    them from there."""
    env = os.environ | {"DANCENET_CACHE": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    out = subprocess.run([sys.executable, "-c", DEFERRED, str(ROOT / "examples" / "example_song.ogg")], cwd=ROOT,
                         env=env, capture_output=True, text=True, check=True).stdout  # fmt: skip
    assert "TWINS [0, 0, 0, 0]" in out
    assert "WARM [1, 1, 1, 1] [False, False, False, True]" in out
    assert len(list((tmp_path / "numba").rglob("*.nbi"))) == 4

COMMERCIAL = """
import json, os, sys
opened, started = [], []


def record(event, args):
    if event == "open" and isinstance(args[0], str | bytes):
        opened.append(os.path.abspath(os.fsdecode(args[0])).replace(os.sep, "/"))
    elif event == "subprocess.Popen":
        started.append(args[1])


sys.addaudithook(record)
from dancenet_core import jit
from dancenet_core.engines.styles import load_style_model
from dancenet_core.licence import NON_COMMERCIAL_FILES
from dancenet_core.warmup import warm_up

jit.defer()  # as in the add-on, where the default mode starts its compiling process
warm_up(commercial=True)
warm = {"opened": len(opened), "bad": [p for p in opened if any(f in p for f in NON_COMMERCIAL_FILES)],
        "started": started, "madmom": any(m.startswith("madmom") for m in sys.modules)}
load_style_model()
warm["control"] = [p for p in opened[warm["opened"]:] if any(f in p for f in NON_COMMERCIAL_FILES)]
print("RESULT", json.dumps(warm))
"""


def test_the_commercial_warm_up_opens_no_non_commercial_file() -> None:
    """In a fresh process, every file opened recorded (an audit hook) from before the core is imported: no weights,
    madmom model or training data file (licence.NON_COMMERCIAL_FILES), no compiling process, no madmom; the
    recorder's control, the style classifier loaded after it, is seen."""
    out = subprocess.run([sys.executable, "-c", COMMERCIAL], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout  # fmt: skip
    warm = json.loads(next(line for line in out.splitlines() if line.startswith("RESULT "))[7:])
    assert warm["opened"] and warm["bad"] == [] and warm["started"] == [] and not warm["madmom"]
    assert [Path(p).name for p in warm["control"]] == ["style_classifier.npz"]


def test_a_warm_up_after_a_warm_up_starts_no_compiling_process(monkeypatch) -> None:
    """The add-on enabled again in the same Blender: its kernels are loaded here already, nothing to compile."""
    from dancenet_core import jit, warmup

    with jit.compiling():
        for step, _ in warmup._kernels().values():
            step()
    monkeypatch.setattr(jit, "_deferred", True)
    started = []
    monkeypatch.setattr(warmup, "_compile_elsewhere", lambda: started.append(1))
    warmup.warm_up()
    assert started == []


def test_a_compiling_process_that_writes_much_to_stderr_is_waited_for(monkeypatch, capsys) -> None:
    """numba's warnings can fill the pipe of the compiling process' stderr: the warm-up reads it as it comes, so
    that process never blocks on a full pipe, and its last line is the reason printed when it fails."""
    import threading

    from dancenet_core import warmup

    monkeypatch.setattr(warmup, "_CHILD", "import sys; sys.stderr.write('numba warning\\n' * 100000); "
                                          "sys.exit('the last line')")
    child = warmup._compile_elsewhere()
    waiting = threading.Thread(target=warmup._finished, args=(child, lambda: False), daemon=True)
    waiting.start()
    waiting.join(30)
    blocked = waiting.is_alive()
    if blocked:  # end the child, so nothing is left running
        child.kill()
        waiting.join(10)
    assert not blocked
    assert "compiling the kernels apart failed (the last line)" in capsys.readouterr().out


needs_stop = pytest.mark.skipif(not hasattr(signal, "SIGSTOP"), reason="no SIGSTOP here: the process runs on at "
                                                                       "below-normal priority instead")


@pytest.fixture
def counting(tmp_path, monkeypatch):
    """The compiling process replaced by one that counts; ended (killed, waited for) after the test."""
    from dancenet_core import warmup

    child = CountingChild(tmp_path)
    monkeypatch.setattr(warmup, "_CHILD", child.code)
    started = []
    real = warmup._compile_elsewhere
    monkeypatch.setattr(warmup, "_compile_elsewhere", lambda: started.append(real()) or started[-1])
    yield child, started
    for compiling in started:
        if compiling.process.returncode is None:
            warmup._finished(compiling, lambda: True)


def test_a_warm_up_whose_dance_raises_ends_its_compiling_process(counting, monkeypatch) -> None:
    """The weights failing to load (say) ends the warm-up: its compiling process is killed and waited for, and
    the file its stderr went to is closed, not left to the interpreter's exit."""
    from dancenet_core import jit, warmup

    child, started = counting

    def broken() -> None:
        raise OSError("the weights are unreadable")

    monkeypatch.setattr(warmup, "_dance", broken)
    monkeypatch.setattr(jit, "_deferred", True)
    monkeypatch.setattr(warmup, "_all_loaded", lambda: False)  # whatever tests before this one loaded
    with pytest.raises(OSError, match="unreadable"):
        warmup.warm_up()
    (compiling,) = started
    assert compiling.process.returncode is not None
    assert compiling.errors.closed
    assert warmup._running is None


@needs_stop
def test_a_generation_stops_the_compiling_process_and_continues_it_after(counting) -> None:
    from dancenet_core import warmup

    child, started = counting
    warmup._compile_elsewhere()
    child.release()  # the kernels a click waits for are written
    assert child.counts()
    with warmup.paused():
        assert child.frozen()
        with warmup.paused():  # a second one under way: the first to end does not continue it
            pass
        assert child.frozen()
    assert child.counts()


@needs_stop
def test_a_generation_lets_the_process_run_until_the_kernels_it_waits_for_are_written(counting) -> None:
    from dancenet_core import warmup

    child, started = counting
    warmup._compile_elsewhere()
    with warmup.paused():
        assert child.counts()  # the analysis' kernels still coming: it runs
        child.release()
        assert child.frozen()  # written: stopped at once
    assert child.counts()


@needs_stop
def test_a_compiling_process_started_during_a_generation_starts_stopped(counting, monkeypatch) -> None:
    """Where no kernel is waited for from it."""
    from dancenet_core import warmup

    child, started = counting
    monkeypatch.setattr(warmup, "WAITED", ())
    with warmup.paused():
        warmup._compile_elsewhere()
        assert child.frozen(1.0)
    assert child.counts()


@needs_stop
def test_a_warm_up_cancelled_during_a_generation_ends_its_stopped_process(counting) -> None:
    """Disabling the add-on while a generation runs: the stopped process is killed, not left stopped for ever,
    and continuing it after is harmless; nothing is coming from it any more."""
    from dancenet_core import jit, warmup

    child, started = counting
    child.release()
    with warmup.paused():
        compiling = warmup._compile_elsewhere()
        assert warmup._finished(compiling, lambda: True) is False
        assert compiling.process.returncode is not None
    assert warmup._running is None
    deadline = time.monotonic() + 10
    while jit.coming() and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not jit.coming()


def test_a_generation_without_a_compiling_process_runs_as_ever() -> None:
    from dancenet_core import warmup

    with warmup.paused():
        assert warmup._running is None
    assert warmup._pausers == 0


class _Kernel:
    signatures: list = []  # never compiled here


def test_a_call_waits_for_a_kernel_that_is_coming_and_runs_the_twin_once_none_is(monkeypatch) -> None:
    import threading

    from dancenet_core import jit

    monkeypatch.setattr(jit, "_deferred", True)
    coming, never, twin = _Kernel(), _Kernel(), object()
    jit.expect(coming, never)
    picked = []
    waiter = threading.Thread(target=lambda: picked.append(jit.pick(coming, twin)))
    waiter.start()
    waiter.join(0.3)
    assert waiter.is_alive() and not picked  # waits for it
    jit.mark_cached(coming)
    waiter.join(10)
    assert picked == [coming]
    waiter = threading.Thread(target=lambda: picked.append(jit.pick(never, twin)))
    waiter.start()
    jit.expect_none()  # the process ended without writing it
    waiter.join(10)
    assert picked == [coming, twin]
    assert jit.pick(_Kernel(), twin) is twin  # nothing coming: the twin at once
