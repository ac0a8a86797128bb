"""The add-on's Commercial Use: the scene's switch, what it needs said on the panel, and a Generate Dance with it
opening no file with a non-commercial or unknown licence (an audit hook records every file opened while the
operator runs; the parts' caches are emptied first, so a part loaded by an earlier test would be opened again);
the preference Commercial Use only, which sets it for every scene and for batch mode, and keeps those files out
of a Blender that enables the add-on with it, its warm-up included (a process of its own, recorded from its
start)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from doubles import CALLS, make_fake_generator, write_song
from scene_helpers import ROOT, bpy, generate, panel_screenshot
from test_addon_library import built_library, real  # noqa: F401 (real: the core's generator, a fixture)

from blender_addon.pipeline import available_styles
from dancenet_core.engines.dancenet import load_bundle
from dancenet_core.engines.styles import load_style_model
from dancenet_core.environment import cache_root
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


def _non_commercial(opened: list[str]) -> list[str]:
    return [p for p in opened if any(f in Path(p).as_posix() for f in NON_COMMERCIAL_FILES)]


@pytest.fixture
def commercial_only(scene, addon):
    """The add-on's preference Commercial Use only, on (after `scene`: a factory reset empties the preferences)."""
    entry = bpy.context.preferences.addons.new()
    entry.module = addon.__name__
    entry.preferences.commercial_only = True
    yield entry.preferences
    bpy.context.preferences.addons.remove(entry)


def test_the_preference_shows_the_scenes_switch_on_and_greyed(scene, addon, commercial_only):
    shot = panel_screenshot()
    assert scene.dancenet.commercial is False
    widgets = shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))
    (switch,) = (w for w in widgets if w.text == "Commercial Use")
    assert switch.kind == "check" and switch.selected and not switch.enabled
    shown = {w.text for w in widgets}
    assert "Set for every scene in Preferences > Add-ons > DanceNet" in shown
    assert "Commercial Use dances with the Motion Library engine" in shown  # what it needs, as with the switch


def _drawn(addon, monkeypatch) -> list[str]:
    """Every file opened while the panel is drawn for DanceNet and for the shipped library (the Style menu lists
    the engine's styles), each part's cache emptied first."""
    global _opened
    monkeypatch.setattr(addon.pipeline, "available_styles", available_styles)  # the real one, not the scene's fake
    monkeypatch.setattr(addon.pipeline, "_styles_cache", [])
    load_bundle.cache_clear()
    library_engine._load_default.cache_clear()
    shot, props = panel_screenshot(), bpy.context.scene.dancenet
    _opened = []
    try:
        for engine in ("dancenet", "library"):
            props.engine, props.library_source, props.library = engine, "FOLDER", ""
            shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0])
    finally:
        opened, _opened = _opened, None
    return opened


def test_with_the_preference_the_panel_opens_no_non_commercial_file(scene, addon, commercial_only, monkeypatch):
    assert not _non_commercial(_drawn(addon, monkeypatch))


def test_without_it_the_panel_is_seen_opening_them(scene, addon, monkeypatch):
    """The recorder's control: DanceNet's styles come from its weights, the shipped library's from its file."""
    opened = [Path(p).as_posix() for p in _drawn(addon, monkeypatch)]
    assert any(p.endswith("dancenet_core/weights/dancenet.npz") for p in opened)
    assert any(p.endswith("dancenet_core/weights/cmu_dance_library.npz") for p in opened)


def test_with_the_preference_batch_mode_dances_for_commercial_use(addon, commercial_only, own_clips, tmp_path):
    from blender_addon import batch

    song = write_song(tmp_path / "song.wav", 0.5)
    code = batch.main([str(song), "--out", str(tmp_path / "out"), "--engine", "library", "--library",
                       str(own_clips)], generator=make_fake_generator())  # fmt: skip
    assert code == 0
    assert CALLS[-1]["commercial"] is True


# A fresh Blender that enables the add-on (as Blender does at start-up, the preference read from the user's
# preferences), every file it opens and every process it starts recorded from the first line; argv: the checkout,
# the preference (on/off), then with it on a song and a built library to Generate Dance with, the scene's switch off.
ENABLED = """
import json, os, sys
opened, started = [], []


def record(event, args):
    if event == "open" and isinstance(args[0], str | bytes):
        opened.append(os.path.abspath(os.fsdecode(args[0])))
    elif event == "subprocess.Popen":
        started.append([os.fsdecode(a) for a in args[1]])


sys.addaudithook(record)
sys.path.insert(0, sys.argv[1])
import bpy
import addon_utils  # on the path once bpy is imported
from blender_addon import preferences

entry = bpy.context.preferences.addons.new()
entry.module = "blender_addon"
if sys.argv[2] == "on":  # stored as Blender stores it: read once the add-on registers its preferences' class
    bpy.utils.register_class(preferences.DanceNetPreferences)
    entry.preferences.commercial_only = True
    bpy.utils.unregister_class(preferences.DanceNetPreferences)
addon = addon_utils.enable("blender_addon")
addon.warming.wait()
out = {"warm_up": {"opened": opened[:], "started": started[:]}}
if sys.argv[2] == "on":
    props = bpy.context.scene.dancenet
    props.music_source, props.music_file, props.engine, props.library = "FILE", sys.argv[3], "library", sys.argv[4]
    props.commercial = False
    out["generate"] = sorted(bpy.ops.dancenet.generate())
    (take,) = (a for _t, a in addon.takes.takes_of(bpy.data.objects["DanceNet Dancer"]))
    out["take_commercial"] = addon.takes.take_info(take)["commercial"]
out["opened"], out["started"] = opened, started
print("RESULT", json.dumps(out), flush=True)
"""


def _enabled(preference: str, tmp_path: Path, *args: str) -> dict:
    """What a fresh Blender enabling the add-on opened and started (ENABLED), its caches the suite's (the built
    library's, numba's), its user folders in `tmp_path`."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_USER_", "DANCENET_"))}
    env.update(HOME=str(tmp_path / "home"), BLENDER_USER_RESOURCES=str(tmp_path / "blender"),
               DANCENET_CACHE=str(cache_root()))
    run = subprocess.run([sys.executable, "-c", ENABLED, str(ROOT), preference, *args], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return json.loads(next(line for line in run.stdout.splitlines() if line.startswith("RESULT "))[7:])


def test_enabled_with_commercial_use_only_blender_opens_no_non_commercial_file(own_clips, tmp_path):
    """Its warm-up starts no compiling process (whose sampler step loads the weights), and a Generate Dance with
    the scene's switch off is made in Commercial Use."""
    song = write_song(tmp_path / "song.wav", 6.0)
    out = _enabled("on", tmp_path, str(song), str(own_clips))
    assert out["warm_up"]["opened"], "the hook recorded nothing"
    assert out["warm_up"]["started"] == []
    assert out["generate"] == ["FINISHED"] and out["take_commercial"] is True
    assert not _non_commercial(out["opened"])


def test_enabled_without_it_blender_is_seen_opening_them(tmp_path):
    """The recorder's control: the warm-up loads DanceNet's weights, and its compiling process is seen started."""
    out = _enabled("off", tmp_path)
    assert any(Path(p).as_posix().endswith("dancenet_core/weights/dancenet.npz") for p in out["warm_up"]["opened"])
    assert any("compile_kernels" in " ".join(argv) for argv in out["warm_up"]["started"])
