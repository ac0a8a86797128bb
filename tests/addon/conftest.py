"""Fixtures of the add-on tests: the registered add-on, an empty scene with the fake generator, a song, the built
extension."""

from __future__ import annotations

from pathlib import Path

import pytest
from doubles import FAKE_STYLES, make_fake_generator, write_song
from scene_helpers import bpy


@pytest.fixture(scope="module")
def addon():
    import blender_addon

    blender_addon.register()
    blender_addon.warming.wait()  # the warm-up's compiles run before the tests, never beside them
    yield blender_addon
    blender_addon.unregister()


@pytest.fixture
def scene(addon, monkeypatch):
    """An empty scene (24 fps: the fake dances at 30, so keys are resampled), the fake generator in place."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    monkeypatch.setattr(addon.pipeline, "load_generator", make_fake_generator)
    monkeypatch.setattr(addon.pipeline, "available_styles", lambda: list(FAKE_STYLES))
    return bpy.context.scene


@pytest.fixture
def song(tmp_path) -> Path:
    return write_song(tmp_path / "Test Song.wav", seconds=2.0)


@pytest.fixture
def real_scene(addon, tmp_path, monkeypatch):
    """An empty 24-fps scene and the real generate_dance (the shipped model), the cache in tmp_path."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.render.fps = 24
    return bpy.context.scene


@pytest.fixture(scope="session")
def zips(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Blender platform -> its zip, built once a session as `python build_addon.py` builds them (wheels from
    .cache/wheels). The tests that build the project (here in build/) are one xdist_group, "build": on one worker,
    they build it one at a time and these zips once."""
    import build_addon

    paths = build_addon.build(tmp_path_factory.mktemp("dist"))
    return {p.stem.rsplit("-", 1)[1].replace("_", "-"): p for p in paths}
