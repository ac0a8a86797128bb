"""The song's sections on the timeline: A1, B1, A2, ... named on their first bars (the generator a stand-in that
reports a form, as generate_dance does)."""

from __future__ import annotations

import signal

import numpy as np
import pytest
from doubles import make_fake_generator, write_song
from scene_helpers import bpy, fcurves_of, generate, panel_screenshot, snapshot

from dancenet_core.music.form import Phrase, Section, SongForm
from tests.made_up import CountingChild, arranged_training_song

FORM = SongForm(np.array([0.0, 0.5, 1.0, 1.5, 2.0]), (Phrase(0, None, 1.0), Phrase(2, 0, 0.9)),
                (Section("A", 1, 0.0, 1.0, 0, 2, 1.0), Section("A", 2, 1.0, 2.0, 2, 2, 0.9)))


def reporting(**fields):
    """The stand-in generator, its result also reporting `fields` (a form, the engine's details) as
    generate_dance does."""
    fake = make_fake_generator()

    def generator(request, progress=None, should_cancel=None):
        result = fake(request, progress, should_cancel)
        for name, value in fields.items():
            setattr(result, name, value)
        return result

    return generator


def test_sections_are_named_on_the_timeline_and_replaced_by_the_next_generate(scene, addon, song, monkeypatch):
    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: reporting(form=FORM))
    scene.timeline_markers.new("A2", frame=40)  # the user's, named like ours
    assert generate(scene, song, seed=1) == {"FINISHED"}
    assert generate(scene, song, seed=2) == {"FINISHED"}
    # The first section on bar 1 (named for it), the return at 1.0 s (frame 25 at 24 fps, between downbeats).
    assert sorted((m.name, m.frame) for m in scene.timeline_markers) == sorted(
        [("A1", 1), ("·", 13), ("·", 25), ("A2", 25), ("·", 37), ("A2", 40)])


def test_section_settings_reach_the_next_generate_and_a_section_is_danced_anew(scene, addon, song, monkeypatch):
    from doubles import CALLS

    from dancenet_core.request import SectionOverride

    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: reporting(form=FORM))
    props = scene.dancenet
    assert not bpy.ops.dancenet.redo_section.poll()  # no take yet
    assert generate(scene, song, seed=3) == {"FINISHED"}
    assert [item.name for item in props.sections] == ["A1", "A2"]  # one settings item per section of the form
    shot = panel_screenshot()
    folds = {c.title: c for c in shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]).children
             if getattr(c, "kind", "") == "panel"}
    drawn = {w.text for w in shot.walk(folds["Sections"])}
    assert {"A1   0.0-1.0 s", "A2   1.0-2.0 s"} <= drawn, drawn
    assert CALLS[-1]["sections"] == ()
    props.sections["A2"].energy = "lively"
    props.sections["A1"].returns = "anew"
    assert generate(scene, song, seed=3) == {"FINISHED"}
    assert CALLS[-1]["sections"] == (SectionOverride("A1", returns="anew"), SectionOverride("A2", energy="lively"))
    rig = bpy.data.objects["DanceNet Dancer"]
    take = rig.animation_data.action
    assert bpy.ops.dancenet.redo_section(section="A2") == {"FINISHED"}
    call = CALLS[-1]
    assert (call["redo_section"], call["energy"], call["seed"]) == ("A2", "lively", 4)
    assert call["continue_from"] is not None and call["at_s"] == pytest.approx(1.0)
    assert rig.animation_data.action.name.endswith("seed 4 · A2 anew") and take.name in bpy.data.actions
    before = snapshot(scene)
    with pytest.raises(RuntimeError, match="has no section 'B7'"):
        bpy.ops.dancenet.redo_section(section="B7")
    assert snapshot(scene) == before
    # Another song: its sections are not known until it is danced, so no section settings reach its dance.
    other = write_song(song.parent / "Other.wav")
    assert generate(scene, other, seed=3) == {"FINISHED"}
    assert CALLS[-1]["sections"] == ()


def test_a_section_of_a_real_dance_danced_anew_in_blender(addon, tmp_path, monkeypatch):
    """The shipped model on a song arranged A B A C A B from training songs: C1 danced anew in a new take, the
    frames before it kept."""
    song = arranged_training_song(tmp_path / "abacab.wav")
    if song is None:
        pytest.skip("the Dance with Melody songs are not here")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 25
    assert generate(scene, song, seed=1) == {"FINISHED"}
    props = scene.dancenet
    names = [item.name for item in props.sections]
    assert names == ["A1", "B1", "A2", "C1", "A3", "B2"], names
    c1 = next(s for s in props.analysis_for(str(song))["sections"] if s["name"] == "C1")
    rig = bpy.data.objects["DanceNet Dancer"]
    frames = range(1, round(c1["end_s"] * 25))
    before = _heads(scene, rig, frames)
    assert bpy.ops.dancenet.redo_section(section="C1") == {"FINISHED"}
    after = _heads(scene, rig, frames)
    cut = round(c1["start_s"] * 25)
    assert np.abs(after[:cut - 1] - before[:cut - 1]).max() < 1e-3  # before C1: kept
    assert np.abs(after[cut + 25:] - before[cut + 25:]).max() > 0.05  # C1: another dance


def _heads(scene, rig, frames) -> np.ndarray:
    out = []
    for f in frames:
        scene.frame_set(f)
        out.append([np.array(rig.matrix_world @ b.head) for b in rig.pose.bones])
    return np.array(out)


def test_a_library_take_lists_its_figures(scene, addon, song, monkeypatch):
    figures = [{"clip": "salsa/01.bvh", "clip_s": [3.0, 5.0], "song_s": [0.0, 1.0], "ratio": 1.0},
               {"clip": "swing/07.bvh", "clip_s": [0.5, 2.5], "song_s": [1.0, 2.0], "ratio": 2.0}]
    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: reporting(details=[{"danced_figures": figures}]))
    assert generate(scene, song, seed=3) == {"FINISHED"}
    shot = panel_screenshot()
    folds = {c.title: c for c in shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]).children
             if getattr(c, "kind", "") == "panel"}
    drawn = [w.text for w in shot.walk(folds["Figures"]) if w.text]
    assert drawn == ["   0.0-1.0 s   salsa/01.bvh  3.0-5.0 s", "   1.0-2.0 s   swing/07.bvh  0.5-2.5 s"], drawn


def test_a_generation_on_the_calling_thread_waits_for_the_warm_up_step(scene, addon, song):
    """Scripts, background mode and batch generate on the calling thread: never beside a warm-up step (a
    generation beside one once ended in a segmentation fault), as a worker's job never is."""
    import threading

    from dancenet_core.errors import DanceNetError

    started = threading.Event()

    def generator(request, progress=None, should_cancel=None):
        started.set()
        raise DanceNetError("stopped here: nothing is applied off the main thread")

    def generate() -> None:
        with pytest.raises(DanceNetError, match="stopped here"):
            addon.pipeline.generate_now(bpy.context, plan, generator)

    scene.dancenet.music_source, scene.dancenet.music_file = "FILE", str(song)
    plan = addon.pipeline.prepare(scene)
    addon.warming.LOCK.acquire()  # a warm-up step under way
    try:
        worker = threading.Thread(target=generate)
        worker.start()
        assert not started.wait(0.5)  # waits for the step
    finally:
        addon.warming.LOCK.release()
    worker.join(30)
    assert started.is_set() and not worker.is_alive()


def _keys() -> list[bytes]:
    """Every key of every action, as bytes."""
    keys = []
    for action in sorted(bpy.data.actions, key=lambda a: a.name):
        for curve in sorted(fcurves_of(action), key=lambda c: (c.data_path, c.array_index)):
            co = np.empty(len(curve.keyframe_points) * 2, np.float32)
            curve.keyframe_points.foreach_get("co", co)
            keys.append(co.tobytes())
    return keys


@pytest.mark.skipif(not hasattr(signal, "SIGSTOP"), reason="no SIGSTOP here: the compile runs on at below-normal "
                                                           "priority beside the click")
def test_a_generation_stops_the_warm_ups_compile_while_it_runs(scene, addon, song, tmp_path, monkeypatch):
    """A first click beside the warm-up: its compiling process is stopped while the dance is made (the click has
    the CPU) and continued after, and the dance is the same bytes as one made with no warm-up running."""
    from dancenet_core import warmup

    child = CountingChild(tmp_path)
    fake = make_fake_generator()
    seen = []

    def generator(request, progress=None, should_cancel=None):
        seen.append(child.frozen())
        return fake(request, progress, should_cancel)

    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: generator)
    assert generate(scene, song, seed=1) == {"FINISHED"}
    alone = _keys()
    monkeypatch.setattr(warmup, "_CHILD", child.code)
    compiling = warmup._compile_elsewhere()
    child.release()  # the kernels a click would wait for are written
    try:
        assert child.counts()
        bpy.ops.wm.read_factory_settings(use_empty=True)
        assert generate(bpy.context.scene, song, seed=1) == {"FINISHED"}
        assert seen[-1]  # stopped while the dance was made
        assert child.counts()  # and counting again after
        assert _keys() == alone and alone
    finally:
        warmup._finished(compiling, lambda: True)


def test_a_style_stays_itself_when_the_engine_and_its_styles_change(scene, addon, song, monkeypatch):
    """The Style menus (the dance's, a section's) list the engine's styles: a style chosen with one engine is the
    same style (or, where the other engine has none of it, said so) when the engine changes, never its
    neighbour's."""
    from doubles import CALLS, FAKE_STYLES

    from dancenet_core.request import SectionOverride

    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: reporting(form=FORM))
    monkeypatch.setattr(addon.library, "library_styles", lambda _folder: ["zouk", FAKE_STYLES[-1], FAKE_STYLES[0]])
    props = scene.dancenet
    assert generate(scene, song, seed=3) == {"FINISHED"}
    a1, a2 = props.sections["A1"], props.sections["A2"]
    a1.style, a2.style, props.style = FAKE_STYLES[0], FAKE_STYLES[1], FAKE_STYLES[-1]
    props.engine = "library"  # its styles: zouk and two of the fake ones, in another order
    assert (a1.style, a2.style, props.style) == (FAKE_STYLES[0], FAKE_STYLES[1], FAKE_STYLES[-1])
    assert generate(scene, song, seed=3) == {"FINISHED"}
    assert CALLS[-1]["sections"] == (SectionOverride("A1", style=FAKE_STYLES[0]),
                                     SectionOverride("A2", style=FAKE_STYLES[1]))
    assert CALLS[-1]["style"] == FAKE_STYLES[-1]
    a2.style = props.style = "zouk"
    props.engine = "dancenet"
    assert (a1.style, a2.style, props.style) == (FAKE_STYLES[0], "zouk", "zouk")
    a2.style = addon.panelsettings.AS_DANCE
    assert a2.style == addon.panelsettings.AS_DANCE and a1.style == FAKE_STYLES[0]
