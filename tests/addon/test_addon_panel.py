"""A panel that reads like Blender's (fake generator): sub-panels in both sidebars, the takes in a
UIList, the missing optional joints in one line, and the scene's true frame rate (fps / fps_base)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from doubles import mixamo_rest, synthetic_motion, write_song
from scene_helpers import MM, bpy, build_armature, fk_world, generate, panel_screenshot, world_heads

from dancenet_core.skeleton import JOINT_NAMES

FOLDS = ["Music", "Dance", "Sections", "Rig", "Takes", "Figures", "Export"]
SHOWN = [f for f in FOLDS if f not in ("Sections", "Figures")]  # no form, no library (test_addon_form.py)
SUMMARY = "30 optional joints not on this rig (fingers: 30)"  # a Mixamo rig without its fingers


def sub_panels(root) -> dict:
    """The recorded sub-panels of a recorded panel, by title."""
    return {child.title: child for child in root.children if getattr(child, "kind", "") == "panel"}


@pytest.mark.parametrize("sidebar", [0, 1], ids=["view3d", "sequencer"])
def test_sub_panels_register_under_the_main_panel_and_draw(scene, addon, song, sidebar):
    shot = panel_screenshot()
    main = addon.panels.MAIN_PANELS[sidebar]
    subs = addon.panels.SUB_PANELS[main.bl_idname]
    assert [s.bl_label for s in subs] == FOLDS
    for sub in subs:
        assert getattr(bpy.types, sub.bl_idname) is sub  # registered
        assert (sub.bl_parent_id, sub.bl_space_type) == (main.bl_idname, main.bl_space_type)
    assert "DEFAULT_CLOSED" in subs[FOLDS.index("Export")].bl_options

    before = sub_panels(shot.record_panel(bpy.context, main))
    assert list(before) == ["Music", "Dance", "Rig"]  # no take and nothing to export yet: those stay hidden
    assert generate(scene, song) == {"FINISHED"}
    root = shot.record_panel(bpy.context, main)
    folds = sub_panels(root)
    assert list(folds) == SHOWN
    assert [f.closed for f in folds.values()] == [False, False, False, False, True]
    own = [child for child in root.children if getattr(child, "kind", "") != "panel"]
    assert "Generate Dance" in {w.text for child in own for w in shot.walk(child)}  # the main panel's, on top
    assert "Seed" in {w.text for w in shot.walk(folds["Dance"])}
    assert "Existing Armature" in {w.text for w in shot.walk(folds["Rig"])}
    assert {"Export FBX", "Export BVH"} <= {w.text for w in shot.walk(folds["Export"])}
    image = shot.paint(root)
    assert image.height > 10 * shot.UNIT


def test_takes_list_shows_the_takes_newest_first_and_a_click_plays_one(scene, addon, song):
    shot = panel_screenshot()
    assert generate(scene, song, takes=3) == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    rig.animation_data.nla_tracks.new().name = "my own track"  # a user's track: not a take, not listed
    takes = [action.name for _track, action in addon.takes.takes_of(rig)]

    def listed() -> list:
        folds = sub_panels(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))
        return [w for w in shot.walk(folds["Takes"]) if w.kind == "item"]

    items = listed()
    assert [w.text for w in items] == takes[::-1]  # newest first, as in the NLA editor
    assert [w.selected for w in items] == [False, False, True]  # the first take plays after a generation

    tracks = list(rig.animation_data.nla_tracks)
    props = scene.dancenet
    props.take_index = next(i for i, t in enumerate(tracks) if t.strips and t.strips[0].action.name == takes[2])
    assert rig.animation_data.action.name == takes[2]
    assert [t.mute for t, _ in addon.takes.takes_of(rig)] == [True, True, False]
    assert [w.selected for w in listed()] == [True, False, False]

    props.take_index = tracks.index(rig.animation_data.nla_tracks["my own track"])  # never chosen as a take
    assert rig.animation_data.action.name == takes[2]
    assert props.take_index == tracks.index(addon.takes.takes_of(rig)[2][0])

    assert bpy.ops.dancenet.choose_take(action=takes[1]) == {"FINISHED"}  # the operator still works, and shows
    assert [w.selected for w in listed()] == [False, True, False]


def test_missing_optional_joints_are_one_line_with_the_list_on_request(scene, addon, song):
    shot = panel_screenshot()
    props = scene.dancenet
    no_fingers = [row for row in mixamo_rest() if "Hand" not in row[0] or row[0].endswith("Hand")]
    rig = build_armature("No fingers", no_fingers)
    props.music_source, props.music_file, props.target, props.armature = "FILE", str(song), "EXISTING", rig
    recorded = shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))
    assert [w.text for w in recorded if "optional" in w.text] == [SUMMARY]
    shown = {w.text for w in shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))}
    assert not any("index1" in text for text in shown)  # the joints themselves: on demand only
    assert bpy.ops.dancenet.list_missing_joints() == {"FINISHED"}

    _, skipped = addon.rigchoice.resolve_map(rig, None)
    summary = addon.rigchoice.missing_summary(skipped)
    assert summary == SUMMARY
    assert generate(scene, song) == {"FINISHED"}
    assert addon.rigchoice.missing_summary(["jaw (jaw)", "left_foot (LeftToeBase)"]) == (
        "2 optional joints not on this rig (face: 1, toes: 1)"
    )


def test_a_scene_at_29_97_fps_is_keyed_at_its_true_rate(scene, addon, tmp_path):
    """30000/1001 fps: a 20-s dance ends 599.4 frames on (599 keys; at 30 fps it would be 600), each key the dance
    at (frame - first) / 29.97 s."""
    shot = panel_screenshot()
    scene.render.fps, scene.render.fps_base = 30000, 1001
    rate = 30000 / 1001
    shown = {w.text: w for w in shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))}
    assert (shown["Frame Rate"].value, shown["Base"].value) == ("30000", "1001.000")
    assert "29.97 fps" in shown
    song = write_song(tmp_path / "twenty.wav", 20.0)
    assert generate(scene, song) == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    first, last = (round(f) for f in rig.animation_data.action.frame_range)
    assert last - first + 1 == round(20 * rate) == 599
    assert (scene.frame_start, scene.frame_end) == (first, last)
    expected = fk_world(synthetic_motion(20.0, 0).resampled(rate))
    for f in (0, 300, 598):
        scene.frame_set(first + f)
        heads = world_heads(rig, JOINT_NAMES)
        assert np.abs((heads - heads[0]) - (expected[f] - expected[f][0])).max() < MM


@pytest.mark.parametrize("engine", ["dancenet", "library"])
def test_a_style_menu_that_cannot_be_filled_says_why(addon, monkeypatch, engine):
    """An install that cannot import the generator (a dependency missing) is not a model still missing: the
    Dance panel says so under the Style menu, with the import's own reason, instead of an empty menu."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.dancenet.engine = engine
    monkeypatch.setattr(addon.pipeline, "_styles_cache", [])
    for module in ("dancenet_core.generate", "dancenet_core.engines"):
        monkeypatch.setitem(sys.modules, module, None)  # what a missing dependency makes of the import
    shot = panel_screenshot()
    texts = [w.text for w in shot.walk(shot.record_panel(bpy.context, addon.panels.MAIN_PANELS[0]))]
    problem = [t for t in texts if t.startswith("Styles cannot be listed:")]
    assert len(problem) == 1 and "dancenet_core." in problem[0] and "reinstall" in problem[0], texts
