"""Animating in the add-on (fake generator for the wiring; the shipped model in the marked tests): frame
rates, a part of the song, root motion, continue from here, takes on the NLA, menus and presets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from doubles import CALLS, make_fake_generator, synthetic_motion, write_song
from made_up import click_song
from scene_helpers import bpy, fk_world, panel_screenshot, snapshot, world_heads


def test_panel_frame_rate_is_the_scenes_and_the_keys_follow_it(scene, addon, song):
    scene.render.fps = 50
    shot = panel_screenshot()
    shown = {w.text: w for w in shot.walk(shot.record_panel(bpy.context, addon.panels.CLASSES[0]))}
    assert shown["Frame Rate"].value == "50"
    scene.dancenet.music_source, scene.dancenet.music_file = "FILE", str(song)
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert keyed_range() == (1, 100)  # the fake's 2-s dance at 30 fps, slerp-resampled to 50


def test_batch_fps_resamples_onto_the_scene_rate(addon, tmp_path, capsys):
    from blender_addon import batch

    song_path = write_song(tmp_path / "beat.wav", 1.5)
    code = batch.main([str(song_path), "--out", str(tmp_path / "out"), "--fps", "60"], generator=make_fake_generator())
    assert code == 0, capsys.readouterr().out
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "out" / "beat" / "beat.blend"))
    opened = bpy.context.scene
    action = bpy.data.objects["DanceNet Dancer"].animation_data.action
    assert opened.render.fps == 60
    assert round(action.frame_range[1] - action.frame_range[0]) + 1 == 90
    with pytest.raises(SystemExit):
        batch.parse_args([str(song_path), "--out", str(tmp_path), "--fps", "23"])


# --- a part of the song ------------------------------------------------------------------------------


def keyed_range(rig_name: str = "DanceNet Dancer") -> tuple[int, int]:
    start, end = bpy.data.objects[rig_name].animation_data.action.frame_range
    return round(start), round(end)


def test_trimmed_moved_strip_dances_the_audio_heard(scene, addon, tmp_path):
    """24 fps; the 4-s song's strip starts at frame 30, its first second and last half second trimmed off,
    its sound shifted 0.25 s: frames 54-113 play the song from 1.25 s to 3.75 s."""

    song_path = write_song(tmp_path / "long.wav", 4.0)
    scene.render.fps = 24
    scene.sequence_editor_create()
    strip = scene.sequence_editor.strips.new_sound("song", str(song_path), 2, 30)
    strip.frame_offset_start, strip.frame_offset_end, strip.sound_offset = 24, 12, 0.25
    scene.sequence_editor.active_strip = strip
    scene.dancenet.music_source = "STRIP"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert CALLS[-1]["start_s"] == pytest.approx(1.25)
    assert CALLS[-1]["end_s"] == pytest.approx(3.75)
    assert keyed_range() == (54, 113)
    assert (scene.frame_start, scene.frame_end) == (54, 113)
    # Beats of the song (every 0.5 s) are marked where they are heard: song second b at frame 30 + 24 (b - 0.25).
    heard = sorted(m.frame for m in scene.timeline_markers)
    assert heard == [round(30 + 24 * (b - 0.25)) for b in np.arange(1.5, 3.75, 0.5)]

    # Part of the Song narrows it to frames 60-89 (song 1.5 s to 2.75 s).
    scene.dancenet.use_part, scene.dancenet.part_start, scene.dancenet.part_end = True, 60, 89
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert CALLS[-1]["start_s"] == pytest.approx(1.5)
    assert CALLS[-1]["end_s"] == pytest.approx(2.75)
    assert keyed_range() == (60, 89)


def test_part_of_a_song_file_counts_from_the_scene_start(scene, addon, song):

    scene.render.fps, scene.frame_start = 24, 11
    props = scene.dancenet
    props.use_part, props.part_start, props.part_end = True, 23, 46
    props.music_source, props.music_file = "FILE", str(song)
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert CALLS[-1]["start_s"] == pytest.approx(0.5)
    assert CALLS[-1]["end_s"] == pytest.approx(1.5)
    strip = scene.sequence_editor.strips_all[0]
    assert strip.frame_start == 11
    assert keyed_range() == (23, 46)


def test_frames_where_the_song_is_not_heard_are_refused(scene, addon, song):
    scene.render.fps = 24
    scene.sequence_editor_create()
    strip = scene.sequence_editor.strips.new_sound("song", str(song), 1, 1)
    scene.sequence_editor.active_strip = strip
    props = scene.dancenet
    props.music_source, props.use_part, props.part_start, props.part_end = "STRIP", True, 100, 200
    before = snapshot(scene)
    with pytest.raises(RuntimeError, match="Less than 1 s of the song is heard in frames 100-200"):
        bpy.ops.dancenet.generate()
    assert snapshot(scene) == before


def test_batch_start_end_and_root_motion(addon, tmp_path, capsys):
    from blender_addon import batch
    from dancenet_core.bvh import read_bvh

    song_path = write_song(tmp_path / "four.wav", 4.0)
    code = batch.main([str(song_path), "--out", str(tmp_path / "out"), "--fps", "30", "--start", "1", "--end", "2.5",
                       "--root-motion", "root-bone", "--bvh"], generator=make_fake_generator())
    assert code == 0, capsys.readouterr().out
    assert CALLS[-1]["start_s"] == 1.0
    assert CALLS[-1]["end_s"] == 2.5
    assert keyed_range() == (31, 75)  # the strip at frame 1, second 1 heard at frame 31, 1.5 s = 45 frames
    assert read_bvh(tmp_path / "out" / "four" / "four.bvh").names[:2] == ("root", "pelvis")


# --- the shipped model ---------------------------------------------------------------------------------


def test_shipped_model_dances_the_heard_part_of_a_trimmed_strip(real_scene, tmp_path):
    sc = real_scene
    sc.sequence_editor_create()
    strip = sc.sequence_editor.strips.new_sound("song", str(click_song(tmp_path / "clicks.wav", 8.0, 110)), 1, 30)
    strip.frame_offset_start, strip.frame_offset_end = 48, 24  # heard: song 2 s to 7 s, frames 78-197
    sc.sequence_editor.active_strip = strip
    sc.dancenet.music_source, sc.dancenet.seed = "STRIP", 4
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert keyed_range() == (78, 197)
    clicks = 30 + 24 * np.arange(0, 8, 60 / 110)  # where each click is heard on the timeline
    marks = np.array([m.frame for m in sc.timeline_markers])
    assert len(marks) >= 8
    assert marks.min() >= 78
    assert marks.max() <= 197
    assert np.abs(marks[:, None] - clicks[None]).min(axis=1).max() <= 1.0  # every beat marker on a heard click


# --- root motion ---------------------------------------------------------------------------------------


def test_root_bone_and_in_place_keep_the_dance_where_it_belongs(scene, addon, song, tmp_path):
    from dancenet_core.shaping.rootmotion import in_place, read_dance_bvh
    from dancenet_core.skeleton import JOINT_NAMES

    scene.render.fps = 30  # the fake dances at 30 fps: no resampling, so the poses are exact
    props = scene.dancenet
    props.music_source, props.music_file, props.root_motion = "FILE", str(song), "root-bone"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    assert rig.data.bones["pelvis"].parent.name == "root"
    dance = synthetic_motion(2.0, seed=0)
    travelling = fk_world(dance)
    for f in (0, 13, 59):
        scene.frame_set(scene.frame_start + f)
        assert np.abs(world_heads(rig, JOINT_NAMES) - travelling[f]).max() < 1e-3  # the same dance...
        root = np.array(rig.matrix_world @ rig.pose.bones["root"].head)
        assert abs(root[2]) < 1e-6
        assert np.abs(root[:2] - travelling[f, 0, :2]).max() < 1e-3  # ...root under the hips
    # BVH and FBX exports carry the root bone: both read back as the travelling dance.
    assert bpy.ops.dancenet.export_bvh(filepath=str(tmp_path / "d.bvh")) == {"FINISHED"}
    assert bpy.ops.dancenet.export_fbx(filepath=str(tmp_path / "d.fbx")) == {"FINISHED"}
    back = read_dance_bvh(tmp_path / "d.bvh")
    assert np.abs(back.positions() - dance.positions()).max() < 1e-3
    before = set(bpy.data.objects)
    bpy.ops.import_scene.fbx(filepath=str(tmp_path / "d.fbx"))
    fbx = next(o for o in set(bpy.data.objects) - before if o.type == "ARMATURE")
    assert fbx.data.bones["pelvis"].parent.name == "root"
    for f in (0, 40):
        scene.frame_set(scene.frame_start + f + 1)  # Blender's FBX importer starts one frame later
        assert np.abs(world_heads(fbx, JOINT_NAMES) - travelling[f]).max() < 1e-3
        assert np.abs(np.array(fbx.matrix_world @ fbx.pose.bones["root"].head)[:2] - travelling[f, 0, :2]).max() < 1e-3

    # In Place on the same rig: the hips stay over the world origin, the root bone rests.
    props.root_motion = "in-place"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    spot = fk_world(in_place(dance))
    for f in (0, 37):
        scene.frame_set(scene.frame_start + f)
        assert np.abs(world_heads(rig, JOINT_NAMES) - spot[f]).max() < 1e-3
        assert np.abs(np.array(rig.matrix_world @ rig.pose.bones["pelvis"].head)[:2]).max() < 1e-6
        assert np.abs(np.array(rig.pose.bones["root"].matrix_basis) - np.eye(4)).max() < 1e-6


def test_each_take_is_shaped_once(scene, addon, song, monkeypatch):
    """The command line's output path shapes the takes (resampled, root motion applied); keying them does not
    shape them again."""
    from dancenet_core.shaping import takes

    shaped = []
    real = takes.shape_take
    monkeypatch.setattr(takes, "shape_take", lambda *a: shaped.append(a[1:]) or real(*a))
    scene.render.fps = 24  # the fake dances at 30 fps
    props = scene.dancenet
    props.music_source, props.music_file, props.root_motion, props.takes = "FILE", str(song), "in-place", 2
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert shaped == [(24.0, "in-place")] * 2


def test_root_bone_on_a_rig_without_one_is_refused(scene, addon, song):
    scene.dancenet.music_source, scene.dancenet.music_file = "FILE", str(song)
    assert bpy.ops.dancenet.generate() == {"FINISHED"}  # a rig without a root bone, now the target
    scene.dancenet.root_motion = "root-bone"
    before = snapshot(scene)
    with pytest.raises(RuntimeError, match="Root Bone motion needs a bone above the hips; 'pelvis'"):
        bpy.ops.dancenet.generate()
    assert snapshot(scene) == before


# --- continue from here ----------------------------------------------------------------------------------


def evaluated_heads(sc, rig, frames) -> np.ndarray:
    """World joint heads [F, 55, 3] of `rig` at the given frames."""
    from dancenet_core.skeleton import JOINT_NAMES

    out = []
    for f in frames:
        sc.frame_set(f)
        out.append(world_heads(rig, JOINT_NAMES))
    return np.array(out)


def test_continue_from_here_keeps_the_take_before_the_frame(scene, addon, song):
    scene.render.fps = 30
    props = scene.dancenet
    props.music_source, props.music_file, props.style, props.seed = "FILE", str(song), "jazz", 4
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    first_take = rig.animation_data.action
    before = evaluated_heads(scene, rig, range(1, 61))
    keys_before = {fc.data_path + str(fc.array_index): [tuple(k.co) for k in fc.keyframe_points]
                   for fc in first_take.layers[0].strips[0].channelbag(first_take.slots[0]).fcurves}
    scene.frame_set(31)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    call = CALLS[-1]
    assert call["seed"] == 5
    assert call["style"] == "jazz"
    assert call["at_s"] == pytest.approx(1.0)
    new_take = rig.animation_data.action
    assert new_take != first_take
    assert new_take.name.endswith("seed 5 · from frame 31")
    after = evaluated_heads(scene, rig, range(1, 61))
    assert np.abs(after[:30] - before[:30]).max() < 1e-4  # frames 1-30 kept
    assert np.abs(after[30:] - before[30:]).max() > 0.05  # from frame 31 on, another dance
    # The first take is untouched (same keys), kept with a fake user; a second continue takes the next seed.
    assert first_take.use_fake_user
    assert keys_before == {
        fc.data_path + str(fc.array_index): [tuple(k.co) for k in fc.keyframe_points]
        for fc in first_take.layers[0].strips[0].channelbag(first_take.slots[0]).fcurves}
    rig.animation_data.action = first_take
    scene.frame_set(20)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    assert CALLS[-1]["seed"] == 6


def test_continue_needs_a_take_and_a_frame_inside_it(scene, addon, song):
    assert not bpy.ops.dancenet.continue_dance.poll()  # no rig, no take
    scene.render.fps = 30
    scene.dancenet.music_source, scene.dancenet.music_file = "FILE", str(song)
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    scene.frame_set(59)  # the take is frames 1-60: less than a second would be left to dance
    before = snapshot(scene)
    with pytest.raises(RuntimeError, match="Put the current frame inside the take, from frame 3 to 31"):
        bpy.ops.dancenet.continue_dance()
    assert snapshot(scene) == before


def test_shipped_model_root_bone_take_continued_without_a_pop(real_scene, tmp_path, capsys):
    """The real dance on a new rig with a root bone, continued from frame 97: kept before, flowing after."""
    from blender_addon import takes

    sc = real_scene
    props = sc.dancenet
    props.music_file, props.seed, props.root_motion = str(click_song(tmp_path / "clicks.wav", 8.0, 110)), 2, "root-bone"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    first_take = rig.animation_data.action
    assert keyed_range() == (1, 192)
    before = evaluated_heads(sc, rig, range(1, 193))
    travelled = np.linalg.norm(np.ptp(before[:, 0, :2], axis=0))
    sc.frame_set(60)
    root = np.array(rig.matrix_world @ rig.pose.bones["root"].head)
    assert travelled > 0.05
    assert abs(root[2]) < 1e-5
    assert np.abs(root[:2] - before[59, 0, :2]).max() < 1e-4

    sc.frame_set(97)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    assert rig.animation_data.action != first_take
    assert takes.take_info(rig.animation_data.action)["seed"] == 3
    after = evaluated_heads(sc, rig, range(1, 193))
    assert np.abs(after[:96] - before[:96]).max() < 1e-3  # frames 1-96 kept
    assert np.abs(after[110:] - before[110:]).max() > 0.05  # then a new dance
    v = np.diff(after, axis=0)
    step = np.linalg.norm(v, axis=-1).max(axis=1)
    dv = np.linalg.norm(np.diff(v, axis=0), axis=-1).max(axis=1)
    join = {"step": step[95], "step_p95": np.percentile(step, 95), "dv": dv[94:96].max(),
            "dv_p95": np.percentile(dv, 95)}
    assert join["step"] <= join["step_p95"], join
    assert join["dv"] <= join["dv_p95"], join
    # Both takes are NLA tracks; choosing the first plays it again.
    assert [t.mute for t, _a in takes.takes_of(rig)] == [True, False]
    assert bpy.ops.dancenet.choose_take(action=first_take.name) == {"FINISHED"}
    assert np.abs(evaluated_heads(sc, rig, [150]) - before[149]).max() < 1e-4
    with capsys.disabled():
        print(f"\nBlender join at frame 97 (m/frame at 24 fps): {({k: round(float(x), 4) for k, x in join.items()})}")


# --- takes on the NLA -------------------------------------------------------------------------------------


def test_takes_are_nla_tracks_one_playing_switchable(scene, addon, song):
    from dancenet_core.skeleton import JOINT_NAMES

    scene.render.fps = 30
    props = scene.dancenet
    props.music_source, props.music_file, props.takes, props.seed = "FILE", str(song), 3, 2
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    takes = addon.takes.takes_of(rig)
    assert [a.name for _t, a in takes] == [f"Test Song · hiphop · seed 2 · take {k}" for k in (1, 2, 3)]
    assert [t.mute for t, _a in takes] == [False, True, True]
    assert rig.animation_data.action == takes[0][1]

    def dancing(k: int) -> bool:
        scene.frame_set(25)
        return np.abs(world_heads(rig, JOINT_NAMES) - fk_world(synthetic_motion(2.0, 2000 + k))[24]).max() < 1e-3

    assert dancing(0)
    assert not dancing(2)
    assert bpy.ops.dancenet.choose_take(action=takes[2][1].name) == {"FINISHED"}
    assert [t.mute for t, _a in takes] == [True, True, False]
    assert rig.animation_data.action == takes[2][1]
    assert dancing(2)
    assert not dancing(0)
    # Muting in the NLA alone plays the take too (the active action cleared, as animators do in the NLA editor).
    rig.animation_data.action = None
    assert dancing(2)
    with pytest.raises(RuntimeError, match="is not a take on the DanceNet target rig"):
        bpy.ops.dancenet.choose_take(action="no such take")


def test_users_actions_and_nla_tracks_are_never_changed(scene, addon, song):
    rig = addon.rig.create_rig(bpy.context, "Hero", with_mesh=False)
    anim = rig.animation_data_create()
    own = bpy.data.actions.new("hero idle")
    rig.pose.bones["head"].rotation_quaternion = (0.9, 0.1, 0.0, 0.0)
    anim.action = own
    rig.keyframe_insert('pose.bones["head"].rotation_quaternion', frame=1)
    layer = bpy.data.actions.new("hero wave")
    track = anim.nla_tracks.new()
    track.name, track.mute = "hero layer", False
    strip = track.strips.new("wave", 5, layer)
    strip.influence, strip.blend_type = 0.5, "ADD"

    def users_state():
        return {
            "actions": {a.name: [tuple(k.co) for c in (a.layers[0].strips[0].channelbags[0].fcurves
                                                    if a.layers else []) for k in c.keyframe_points]
                        for a in (own, layer)},
            "track": (track.name, track.mute, track.is_solo, [(s.name, s.action.name, s.frame_start, s.influence,
                                                               s.blend_type) for s in track.strips]),
        }

    before = users_state()
    assert before["actions"]["hero idle"]  # the user's keys are there to be compared
    scene.render.fps = 30
    props = scene.dancenet
    props.music_source, props.music_file, props.target, props.armature = "FILE", str(song), "EXISTING", rig
    props.takes = 2
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    scene.frame_set(20)
    assert bpy.ops.dancenet.continue_dance() == {"FINISHED"}
    ours = addon.takes.takes_of(rig)
    assert len(ours) == 3
    assert track not in [t for t, _a in ours]
    assert bpy.ops.dancenet.choose_take(action=ours[1][1].name) == {"FINISHED"}
    assert users_state() == before
    assert own.use_fake_user  # kept for the user, unchanged
    assert len(anim.nla_tracks) == 4


# --- where Blender users look ----------------------------------------------------------------------------


class _Layout:
    """Records the operators a menu function puts in a menu."""

    def __init__(self) -> None:
        self.ops: list[tuple[str, str | None]] = []

    def operator(self, idname: str, text: str | None = None, **_kw) -> None:
        self.ops.append((idname, text))


def test_add_armature_and_file_export_menus(scene, addon, song, tmp_path):
    from types import SimpleNamespace

    drawn = {}
    for menu in (bpy.types.VIEW3D_MT_armature_add, bpy.types.TOPBAR_MT_file_export):
        layout = _Layout()
        for draw in menu._dyn_ui_initialize():  # the functions Menu.append added, Blender's own included
            if draw.__module__.endswith("menus"):
                draw(SimpleNamespace(layout=layout), bpy.context)
        drawn[menu.__name__] = layout.ops
    assert drawn["VIEW3D_MT_armature_add"] == [("dancenet.add_rig", None)]
    assert [op for op, _t in drawn["TOPBAR_MT_file_export"]] == ["dancenet.export_bvh", "dancenet.export_fbx"]

    # What the Add menu entry runs: a rig at the 3D cursor, here with a root bone and no mannequin.
    scene.cursor.location = (1.0, 2.0, 0.0)
    assert bpy.ops.dancenet.add_rig(with_mesh=False, root_bone=True) == {"FINISHED"}
    rig = bpy.context.view_layer.objects.active
    assert tuple(rig.location) == (1.0, 2.0, 0.0)
    assert not rig.children
    assert rig.data.bones["pelvis"].parent.name == "root"
    props = scene.dancenet
    props.music_source, props.music_file, props.target, props.armature = "FILE", str(song), "EXISTING", rig
    props.root_motion = "root-bone"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    # What the Export menu entries run: the dance of the active rig, root bone included.
    assert bpy.ops.dancenet.export_bvh(filepath=str(tmp_path / "menu.bvh")) == {"FINISHED"}
    assert "ROOT root" in (tmp_path / "menu.bvh").read_text()[:100]


def test_presets_save_and_restore_the_settings(scene, addon):
    props = scene.dancenet
    props.style, props.seed, props.temperature, props.takes, props.root_motion = "jazz", 7, 0.4, 3, "in-place"
    assert bpy.ops.dancenet.preset_add(name="Jazz on the spot") == {"FINISHED"}
    preset = Path(bpy.utils.user_resource("SCRIPTS", path="presets/dancenet/settings")) / "Jazz_on_the_spot.py"
    assert preset.is_file()
    props.style, props.seed, props.temperature, props.takes, props.root_motion = "auto", 0, 0.1, 1, "travel"
    assert bpy.ops.script.execute_preset(filepath=str(preset), menu_idname="DANCENET_MT_presets") == {"FINISHED"}
    assert (props.style, props.seed, props.takes, props.root_motion) == ("jazz", 7, 3, "in-place")
    assert props.temperature == pytest.approx(0.4)


# --- any humanoid rig ---------------------------------------------------------------------------------------
