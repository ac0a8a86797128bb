"""Issue 26 item 14: `--render` without what it needs says, in one line, what a pip user installs (not the
checkout's Debian list), and the PyOpenGL that pyrender pins (3.1.0, which crashes) is named before any work."""

from __future__ import annotations

import importlib.metadata
import importlib.util
from typing import Any

import pytest

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


def test_pyrenders_pinned_pyopengl_is_named_with_the_fix(monkeypatch: pytest.MonkeyPatch) -> None:
    version = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "3.1.0" if name == "PyOpenGL" else version(name))
    with pytest.raises(DanceNetError) as e:
        render.gl_platform()
    assert 'PyOpenGL 3.1.0' in str(e.value) and 'pip install "PyOpenGL==3.1.10"' in str(e.value)
