"""The add-on's Commercial Use switch: what it needs said on the panel, and a Generate Dance with it opening no file
with a non-commercial or unknown licence (an audit hook records every file opened under the package, madmom and
the data folder while the operator runs; the parts' caches are emptied first, so a part loaded by an earlier test
would be opened again)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from scene_helpers import bpy, generate, panel_screenshot
from test_addon_library import built_library, real  # noqa: F401 (real: the core's generator, a fixture)

from dancenet_core.engines.styles import load_style_model
from dancenet_core.library import engine as library_engine
from dancenet_core.licence import NON_COMMERCIAL_FILES

_opened: list[str] | None = None  # the files opened while recording; None: not recording


def _hook(event: str, args: tuple) -> None:
    if _opened is not None and event == "open" and isinstance(args[0], str | bytes):
        _opened.append(os.path.abspath(os.fsdecode(args[0])))


sys.addaudithook(_hook)  # hooks cannot be removed: this one records only between `_opened = []` and `= None`


@pytest.fixture(scope="module")
def own_clips(tmp_path_factory) -> Path:
    return built_library(tmp_path_factory.mktemp("own"), (("waltz/a", 84, 0.0), ("waltz/b", 90, 1.0),
                                                          ("tango/c", 126, 2.0)))


def _recorded(scene, real, folder: Path, commercial: bool) -> tuple[set[str], list[str]]:  # noqa: F811
    """Generate Dance on the library of `folder`, and every file it opened."""
    global _opened
    _opened = []
    try:
        done = generate(scene, real, engine="library", library=str(folder), commercial=commercial)
    finally:
        opened, _opened = _opened, None
    return done, opened


def test_the_switch_says_what_it_needs(scene, addon):
    shot = panel_screenshot()
    props = scene.dancenet
    props.commercial, props.engine = True, "dancenet"
    shown = {w.text for w in shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))}
    assert "Commercial Use" in shown and "Commercial Use dances with the Motion Library engine" in shown
    props.engine, props.library_source, props.library = "library", "FOLDER", ""
    shown = {w.text for w in shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))}
    assert "Commercial Use needs a library of your own clips" in shown


def test_generate_dance_for_commercial_use_opens_no_non_commercial_file(scene, addon, real, own_clips):  # noqa: F811
    load_style_model.cache_clear()
    library_engine._load_match.cache_clear()
    library_engine._load_default.cache_clear()
    done, opened = _recorded(scene, real, own_clips, commercial=True)
    assert done == {"FINISHED"}
    assert opened, "the hook recorded nothing (the built library is read at least)"
    bad = [p for p in opened if any(f in Path(p).as_posix() for f in NON_COMMERCIAL_FILES)]
    assert not bad
    (take,) = (a for _t, a in addon.takes.takes_of(bpy.data.objects["DanceNet Dancer"]))
    assert addon.takes.take_info(take)["commercial"] is True


def test_the_default_generate_dance_is_seen_opening_them(scene, addon, real, own_clips):  # noqa: F811
    """The recorder's control: the same dance without the switch opens the style classifier (its styles are the
    library's) and says so in no licence of its own."""
    load_style_model.cache_clear()
    done, opened = _recorded(scene, real, own_clips, commercial=False)
    assert done == {"FINISHED"}
    assert any(Path(p).as_posix().endswith("dancenet_core/weights/style_classifier.npz") for p in opened)
