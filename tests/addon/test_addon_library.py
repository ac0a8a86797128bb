"""The motion-library engine from the add-on: the panel's Engine and Library settings, a take
danced from a library (one the test writes, and the shipped CMU one), Continue From Here and bad folders answered
in one line, the Style menu's styles from the library, batch mode with --engine library; and Build Library, which
builds a folder in Blender (no torch)."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from doubles import write_song
from scene_helpers import bpy, fcurves_of, generate, modal_stand_in, panel_screenshot, snapshot, world_heads

from dancenet_core.bvh import BvhData, write_bvh, write_bvh_data
from dancenet_core.engines import ENGINES
from dancenet_core.errors import GenerationCancelled
from dancenet_core.generate import generate_dance
from dancenet_core.library.build import build_library
from dancenet_core.library.store import library_path
from dancenet_core.motion import Motion
from dancenet_core.request import options
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_INDEX

SONG_S = 6.0


def _clip(seconds: float, bpm: float, phase: float) -> Motion:
    """Legs and arms swinging a cycle every two beats, the pelvis bobbing and walking forward."""
    fps = 25.0
    t = np.arange(round(seconds * fps)) / fps
    s = np.sin(np.pi * bpm / 60 * t + phase)
    rot = np.zeros((len(t), DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_hip"], 0], rot[:, JOINT_INDEX["right_hip"], 0] = 0.5 * s, -0.5 * s
    rot[:, JOINT_INDEX["left_shoulder"], 2], rot[:, JOINT_INDEX["right_shoulder"], 2] = -1.2 + 0.4 * s, 1.2 + 0.4 * s
    root = np.stack([0.05 * s, 0.9 + 0.02 * np.cos(2 * np.pi * bpm / 60 * t), 0.3 * t], axis=1)
    return Motion(rot, root, fps)


def built_library(folder: Path, clips: tuple[tuple[str, float, float], ...]) -> Path:
    """`folder` as a built library of 12-s clips, each (style/name, its tempo, its phase)."""
    for name, bpm, phase in clips:
        (folder / name).parent.mkdir(exist_ok=True)
        write_bvh(folder / f"{name}.bvh", _clip(12.0, bpm, phase))
    build_library(folder, report=lambda _line: None)
    return folder


@pytest.fixture(scope="module")
def library_folder(tmp_path_factory) -> Path:
    """A built library of three 12-s clips in two styles (folders)."""
    return built_library(tmp_path_factory.mktemp("library"),
                         (("swing/a", 110, 0.0), ("swing/b", 120, 1.0), ("salsa/c", 100, 2.0)))


@pytest.fixture
def real(addon, scene, monkeypatch, tmp_path):
    """The core's generate_dance in place of the fake generator; a 6-s song at 120 BPM."""
    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: generate_dance)
    return write_song(tmp_path / "Library Song.wav", SONG_S)


def _takes(addon, rig) -> list:
    return [action for _track, action in addon.takes.takes_of(rig)]


def test_the_panels_engines_are_the_cores(addon):
    engine = next(o for name, _d, o in options() if name == "engine")
    assert {value for value, _label, _help in engine.choices} == set(ENGINES)


@pytest.mark.parametrize("engine", ["dancenet", "library"])
def test_the_library_folder_is_drawn_only_for_the_library_engine(scene, addon, engine):
    shot = panel_screenshot()
    scene.dancenet.engine = engine
    root = shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0])
    shown = {w.text for w in shot.walk(root)}
    assert "Engine" in shown
    assert ("Library" in shown) == (engine == "library")


def test_a_take_from_a_library_then_another(scene, addon, real, library_folder):
    assert generate(scene, real, engine="library", library=str(library_folder), seed=4) == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    (first,) = _takes(addon, rig)
    info = addon.takes.take_info(first)
    assert (info["engine"], info["library"], info["seed"]) == ("library", str(library_folder), 4)
    assert info["style"] == "any"  # the music classifier knows neither of the library's styles: any clip dances
    frames = first.frame_range[1] - first.frame_range[0] + 1
    assert abs(frames - SONG_S * scene.render.fps) <= 2
    assert generate(scene, real, seed=5) == {"FINISHED"}
    assert len(_takes(addon, rig)) == 2
    assert rig.animation_data.action != first  # the new take plays; the first is kept on its track


def test_the_style_menu_offers_the_librarys_styles(scene, addon):
    props = scene.dancenet
    with pytest.raises(TypeError):
        props.style = "salsa"  # DanceNet's (here the fake model's) styles
    props.engine, props.library = "library", ""
    props.style = "salsa"  # the shipped CMU library's
    names = [item[0] for item in addon.properties._styles(props, bpy.context)]
    assert names == ["auto", "indian", "latin", "modern", "salsa", "swing"]
    props.library = str(Path(bpy.app.tempdir) / "no such library")
    items = addon.properties._styles(props, bpy.context)
    assert [item[0] for item in items] == ["auto", "salsa"] and "not this engine's" in items[1][1]  # kept, said so
    assert props.style == "salsa"


def test_a_style_of_the_library_is_danced(scene, addon, real, library_folder):
    assert generate(scene, real, engine="library", library=str(library_folder), style="salsa") == {"FINISHED"}
    (take,) = _takes(addon, bpy.data.objects["DanceNet Dancer"])
    assert addon.takes.take_info(take)["style"] == "salsa"


def test_the_shipped_library_when_no_folder_is_given(scene, addon, real):
    assert generate(scene, real, engine="library", library="", root_motion="in-place") == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    (take,) = _takes(addon, rig)
    info = addon.takes.take_info(take)
    assert (info["engine"], info["library"], info["root_motion"]) == ("library", None, "in-place")
    motion = addon.takes.take_motion(take)
    assert np.ptp(motion.rotations[:, JOINT_INDEX["left_knee"]], axis=0).max() > 0.3  # it dances, not stands


def test_continue_from_here_on_a_library_take(scene, addon, real, library_folder):
    """Continue from here with the library engine: the take before the frame is kept, the rest danced anew."""
    generate(scene, real, engine="library", library=str(library_folder))
    rig = bpy.data.objects["DanceNet Dancer"]
    first_take = rig.animation_data.action
    bpy.context.view_layer.objects.active = rig
    frames = range(scene.frame_start, scene.frame_start + 120)
    before = _heads(scene, rig, frames)
    scene.frame_set(scene.frame_start + 60)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    assert rig.animation_data.action != first_take
    after = _heads(scene, rig, frames)
    # The frames before the continued one kept, within 1 mm as the shipped model's continued take (Blender 5.2 keys
    # them 0.22 mm off the first take, 4.5 under 0.1 mm).
    assert np.abs(after[:60] - before[:60]).max() < 1e-3
    assert np.abs(after[60:] - before[60:]).max() > 0.05  # from it on, another dance


def _heads(scene, rig, frames: range) -> np.ndarray:
    """World joint heads [F, 55, 3] of `rig` at `frames`."""
    out = []
    for f in frames:
        scene.frame_set(f)
        out.append(world_heads(rig, DEFAULT_SKELETON.names))
    return np.array(out)


@pytest.mark.parametrize(("folder", "message"), [
    ("missing", "motion library folder not found"),
    ("empty", "is not built"),
    ("unbuilt", "is not built"),
])
def test_a_bad_library_folder_is_reported_and_the_rig_kept(scene, addon, real, tmp_path, folder, message):
    path = tmp_path / folder
    if folder != "missing":
        path.mkdir()
    if folder == "unbuilt":
        write_bvh(path / "clip.bvh", _clip(6.0, 110, 0.0))
    rig = addon.rig.create_rig(bpy.context, with_mesh=False)
    rig.animation_data_create().action = bpy.data.actions.new("user's own")
    scene.dancenet.target, scene.dancenet.armature = "EXISTING", rig
    before = snapshot(scene)
    with pytest.raises(RuntimeError) as report:
        generate(scene, real, engine="library", library=str(path))
    text = str(report.value)
    assert text.startswith("Error: ") and message in text and "Traceback" not in text
    before["props"].update(music_source="FILE", music_file=str(real), engine="library", library=str(path))
    assert snapshot(scene) == before
    assert rig.animation_data.action.name == "user's own"


def test_batch_mode_dances_from_the_shipped_library(addon, tmp_path, capfd):
    from blender_addon import batch

    song = write_song(tmp_path / "batch song.wav", SONG_S)
    code = batch.main([str(song), "--out", str(tmp_path / "out"), "--bvh", "--engine", "library", "--takes", "2"],
                      generator=generate_dance)
    out = capfd.readouterr().out
    assert code == 0, out
    assert out.splitlines()[-1] == "1 of 1 songs done", out
    assert out.startswith("OK      batch song.wav: any, 6.0 s, 2 takes"), out
    bvh = (tmp_path / "out" / "batch_song" / "batch_song.bvh").read_text()  # the take that plays, exported
    frames = int(next(line for line in bvh.splitlines() if line.startswith("Frames:")).split(":")[1])
    assert abs(frames - SONG_S * 25) <= 2, frames  # at the engine's own 25 fps


@pytest.fixture
def own_cache(monkeypatch, tmp_path) -> Path:
    """A cache of this test's own: a folder built by another test (or run) must not read as built here."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _two_clips(folder: Path) -> Path:
    """Two made-up 12-s clips in two styles (folders), and a 0.5-s one the build leaves out."""
    for name, bpm, phase, seconds in (("swing/one", 115, 0.5, 12.0), ("salsa/two", 105, 1.5, 12.0),
                                      ("salsa/blip", 105, 0.0, 0.5)):  # fmt: skip
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        write_bvh(folder / f"{name}.bvh", _clip(seconds, bpm, phase))
    return folder


def _library_row(scene, folder: Path | str) -> list[tuple[str, str]]:
    """The Dance panel's Build Library button and what it says beside it, as (text, icon) pairs."""
    scene.dancenet.engine, scene.dancenet.library = "library", str(folder)
    shot = panel_screenshot()
    widgets = shot.walk(shot.record_panel(bpy.context))
    k = next((i for i, w in enumerate(widgets) if w.text == "Build Library"), None)
    return [] if k is None else [(w.text, w.icon) for w in widgets[k : k + 2]]


def test_build_library_then_a_dance_from_it(scene, addon, real, own_cache, tmp_path):
    folder = _two_clips(tmp_path / "my clips")
    assert _library_row(scene, folder) == [("Build Library", "FILE_REFRESH"), ("Not built yet", "INFO")]
    assert [item[0] for item in addon.properties._styles(scene.dancenet, bpy.context)] == ["auto"]
    before = snapshot(scene)
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    assert snapshot(scene) == before  # building touches nothing in the file
    assert library_path(folder).is_file()
    assert _library_row(scene, folder)[1] == ("Built", "CHECKMARK")
    assert [item[0] for item in addon.properties._styles(scene.dancenet, bpy.context)] == ["auto", "salsa", "swing"]
    assert generate(scene, real, engine="library", library=str(folder), style="swing") == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    (take,) = _takes(addon, rig)
    assert addon.takes.take_info(take)["style"] == "swing"
    keys = {len(c.keyframe_points) for c in fcurves_of(take)}
    assert min(keys) >= SONG_S * scene.render.fps - 2  # every channel keyed over the song
    motion = addon.takes.take_motion(take)
    assert np.ptp(motion.rotations[:, JOINT_INDEX["left_hip"]], axis=0).max() > 0.3  # the clips' swing, danced


def test_build_library_in_the_background_reports_one_line(scene, addon, own_cache, tmp_path):
    folder = _two_clips(tmp_path / "clips")
    scene.dancenet.engine, scene.dancenet.library = "library", str(folder)
    op = modal_stand_in(addon.operators.DANCENET_OT_build_library)
    op._begin(bpy.context, addon.library.build_job(scene.dancenet))
    runtime = bpy.context.window_manager.dancenet
    assert runtime.running and not bpy.ops.dancenet.generate.poll()  # one job at a time
    op._job.join(120)
    assert op.modal(bpy.context, SimpleNamespace(type="TIMER")) == {"FINISHED"}
    assert not runtime.running
    assert op.reports == [({"INFO"}, "Built library: 2 clips, 0.4 min, styles salsa, swing; left out 1 file: "
                                     "blip.bvh: 0.48 s, too short to hold a bar")]


def test_build_library_cancelled_with_esc_writes_nothing(scene, addon, own_cache, tmp_path):
    from blender_addon import warming

    folder = _two_clips(tmp_path / "clips")
    scene.dancenet.engine, scene.dancenet.library = "library", str(folder)
    op = modal_stand_in(addon.operators.DANCENET_OT_build_library)
    with warming.LOCK:  # the worker waits for the lock, so Esc comes before its first clip
        op._begin(bpy.context, addon.library.build_job(scene.dancenet))
        op._job.poll()  # no FBX to sample: the worker starts
        assert op.modal(bpy.context, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    op._job.join(60)
    assert isinstance(op._job.error, GenerationCancelled)
    assert op.reports == [({"WARNING"}, "DanceNet: cancelled; nothing was changed")]
    assert not library_path(folder).is_file() and not bpy.context.window_manager.dancenet.running


def _not_a_dancer(folder: Path) -> None:
    """A BVH of three joints in a row, and a file that is no BVH at all."""
    write_bvh_data(folder / "snake.bvh", BvhData(("a", "b", "c"), (-1, 0, 1), np.eye(3), (
        ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
        ("Zrotation", "Xrotation", "Yrotation"), ("Zrotation", "Xrotation", "Yrotation")), (), 0.04,
        np.zeros((50, 12))))  # fmt: skip
    (folder / "notes.bvh").write_text("these are my notes, not motion\n")


@pytest.mark.parametrize(("folder", "message"), [
    ("missing", "motion library folder not found: "),
    ("empty", "no BVH clips in "),
    ("unreadable", "none of the 2 clips in "),
])  # fmt: skip
def test_a_bad_folder_to_build_is_one_line_and_the_users_actions_kept(scene, addon, own_cache, tmp_path, folder,
                                                                       message):
    path = tmp_path / folder
    if folder != "missing":
        path.mkdir()
    if folder == "unreadable":
        _not_a_dancer(path)
    rig = addon.rig.create_rig(bpy.context, with_mesh=False)
    rig.animation_data_create().action = bpy.data.actions.new("user's own")
    scene.dancenet.target, scene.dancenet.armature = "EXISTING", rig
    state = {"missing": ("Folder not found", "ERROR"), "empty": ("No BVH or FBX clips in it", "ERROR"),
             "unreadable": ("Not built yet", "INFO")}[folder]
    assert _library_row(scene, path)[1] == state
    before = snapshot(scene)
    with pytest.raises(RuntimeError) as report:
        bpy.ops.dancenet.build_library()
    text = str(report.value).strip()
    assert text.startswith("Error: ") and message in text, text
    assert len(text.splitlines()) == 1 and "Traceback" not in text
    assert snapshot(scene) == before
    assert rig.animation_data.action.name == "user's own" and not bpy.data.actions["user's own"].use_fake_user


def test_no_build_button_for_the_shipped_library(scene, addon):
    assert _library_row(scene, "") == []
    scene.dancenet.library = ""
    with pytest.raises(RuntimeError, match="Choose the Library folder of BVH clips to build"):
        bpy.ops.dancenet.build_library()


def test_a_clip_whose_name_is_not_utf8_is_reported_as_blender_can_show_it(scene, addon, own_cache, tmp_path):
    """A Latin-1 `caf\\xe9.bvh` in the folder (from an old archive): the library builds, and the line about the
    clip it leaves out shows the byte that is not UTF-8 as U+FFFD (Blender's text takes UTF-8 only)."""
    folder = _two_clips(tmp_path / "clips")
    (folder / os.fsdecode(b"caf\xe9.bvh")).write_text("not a clip")
    scene.dancenet.engine, scene.dancenet.library = "library", str(folder)
    op = modal_stand_in(addon.operators.DANCENET_OT_build_library)
    op._begin(bpy.context, addon.library.build_job(scene.dancenet))
    op._job.join(120)
    assert op.modal(bpy.context, SimpleNamespace(type="TIMER")) == {"FINISHED"}
    ((kind, line),) = op.reports
    assert kind == {"INFO"} and "left out 2 files: " in line and f"{folder}/caf\ufffd.bvh:1:" in line
    line.encode("utf-8")  # no lone surrogate left: Blender's report would refuse it
