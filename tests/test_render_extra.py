"""Issue 26 item 14: `--render` without what it needs says, in one line, what a pip user installs (not the
checkout's Debian list); the PyOpenGL that pyrender pins (3.1.0) draws on Python 3.11 and is named with the fix
before any work on 3.13, where it cannot; a render worker's error reaches the caller as its text."""

from __future__ import annotations

import ctypes
import importlib.metadata
import importlib.util
from typing import Any

import numpy as np
import pytest
from made_up import small_motion

from dancenet_core import render
from dancenet_core.errors import DanceNetError


@pytest.fixture(autouse=True)
def fresh_platform() -> Any:
    render.gl_platform.cache_clear()
    yield
    render.gl_platform.cache_clear()


def test_without_the_render_extra_a_pip_user_is_told_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyrender" else find_spec(name))
    with pytest.raises(DanceNetError) as e:
        render.gl_platform()
    message = str(e.value)
    assert 'pip install "dancenet[render]"' in message and "pyrender missing" in message, message
    assert "apt-packages" not in message and "\n" not in message


def test_pyrenders_pinned_pyopengl_is_named_with_the_fix_where_it_cannot_draw(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """PyOpenGL 3.1.0 (pyrender's pin) draws on Python 3.11 and is let through there; on 3.13 it cannot, and
    the message names the version to install."""
    version = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "3.1.0" if name == "PyOpenGL" else version(name))
    monkeypatch.setattr(render, "_MIN_PYOPENGL", (3, 1, 0))  # Python 3.11's floor
    render._check_render_extra()
    monkeypatch.setattr(render, "_MIN_PYOPENGL", (3, 1, 10))  # Python 3.13's
    with pytest.raises(DanceNetError) as e:
        render.gl_platform()
    assert 'PyOpenGL 3.1.0' in str(e.value) and 'pip install "PyOpenGL==3.1.10"' in str(e.value)


def test_a_render_workers_error_comes_back_as_its_text(monkeypatch: pytest.MonkeyPatch) -> None:
    """PyOpenGL's errors carry ctypes arguments that cannot be pickled; a worker's error used to arrive as
    `cannot pickle '_ctypes.CArgObject'` and hide its cause. Now the caller gets the cause in one line."""

    class BrokenStage:
        def __init__(self, *args: Any) -> None:
            raise ctypes.ArgumentError("argument 2: no handler", ctypes.byref(ctypes.c_int()))

    monkeypatch.setattr(render, "_Stage", BrokenStage)  # forked workers inherit it
    motion = small_motion(render._PARALLEL_MIN_FRAMES + 4)
    with pytest.raises(RuntimeError, match="the preview's renderer failed: ArgumentError: .*no handler"):
        list(render.iter_frames(motion, np.arange(motion.num_frames), 32, 24, workers=2))
