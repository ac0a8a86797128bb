"""`--render` without what it needs says, in one line, what a pip user installs (not the
checkout's Debian list); the PyOpenGL that pyrender pins (3.1.0) draws on Python 3.11 and 3.13; a render
worker's error reaches the caller as its text."""

from __future__ import annotations

import ctypes
import importlib.util
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from made_up import small_motion

from dancenet_core import render
from dancenet_core.errors import DanceNetError
from dancenet_core.render import frames


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


_WITHOUT_THE_NEW_NAME = """
import ctypes
from OpenGL.plugins import FormatHandler
from dancenet_core.render import pyopengl_compat
byref = type(ctypes.byref(ctypes.c_int()))
name = f"{byref.__module__}.{byref.__name__}"
FormatHandler.registry[:] = [p for p in FormatHandler.registry if name not in getattr(p, "check", ())]
assert FormatHandler.match(byref) is None
count = len(FormatHandler.registry)
pyopengl_compat()
assert FormatHandler.match(byref).import_path.endswith("CtypesParameterHandler")
pyopengl_compat()  # a second call adds nothing
assert len(FormatHandler.registry) == count + 1
"""


def test_pyrenders_pinned_pyopengl_takes_byref_arguments() -> None:
    """PyOpenGL 3.1.0 (what `pip install ".[render]"` gets, pyrender's pin) knows ctypes' byref type only by its
    pre-3.12 name, so on Python 3.13 pyrender's contexts failed; `pyopengl_compat` registers the new name. Here
    PyOpenGL's own registration is taken away, as 3.1.0 lacks it (in a child: OpenGL loaded in the test process
    would stop the renderer choosing its platform)."""
    subprocess.run([sys.executable, "-c", _WITHOUT_THE_NEW_NAME], check=True, cwd=Path(__file__).parents[1])


def test_a_render_workers_error_comes_back_as_its_text(monkeypatch: pytest.MonkeyPatch) -> None:
    """PyOpenGL's errors carry ctypes arguments that cannot be pickled; a worker's error must not arrive as
    `cannot pickle '_ctypes.CArgObject'`, hiding its cause: what a worker raises pickles, with the cause in
    its one line (the worker's function is called here as the pool calls it)."""

    class BrokenStage:
        def __init__(self, *args: Any) -> None:
            raise ctypes.ArgumentError("argument 2: no handler", ctypes.byref(ctypes.c_int()))

    motion = small_motion(8)
    monkeypatch.setattr(frames, "_Stage", BrokenStage)
    monkeypatch.setattr(frames, "_worker_state", {"motion": motion, "size": (32, 24), "floor": 0.0, "cams": []})
    with pytest.raises(RuntimeError, match="the preview's renderer failed: ArgumentError: .*no handler") as e:
        frames._worker_draw(np.arange(2))
    assert str(pickle.loads(pickle.dumps(e.value))) == str(e.value)
