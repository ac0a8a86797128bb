"""The Blender add-on under pip bpy (no GUI): rig, keyframes, retargeting, operators, exports, batch.

The generator is `fake_generate_dance` (tests/addon/doubles.py): real Motions of synthetic
rotations, so these tests check the add-on, not the model. Blender's user folders point at a scratch
directory; tests that need a fresh Blender run in a subprocess.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from doubles import make_fake_generator, mixamo_rest, rigify_rest, synthetic_motion, write_song
from made_up import read_video
from scene_helpers import (
    BLENDER_ENV,
    IDENTITY_MAP,
    MM,
    ROOT,
    assert_dances_like,
    bpy,
    build_armature,
    fcurves_of,
    fk_world,
    generate,
    modal_stand_in,
    panel_screenshot,
    snapshot,
    world_heads,
)

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError, GenerationCancelled
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_NAMES

# --- rig -------------------------------------------------------------------------------------------


def test_new_rig_has_the_skeleton_and_a_skinned_mannequin(scene, addon):
    from blender_addon import rigdef

    rig = addon.rig.create_rig(bpy.context)
    assert sorted(b.name for b in rig.data.bones) == sorted(JOINT_NAMES)
    for j, name in enumerate(JOINT_NAMES):
        parent = rig.data.bones[name].parent
        assert (parent.name if parent else None) == (JOINT_NAMES[DEFAULT_SKELETON.parents[j]] if j else None)
    expected = rigdef.rest_heads(DEFAULT_SKELETON) @ rigdef.Y_UP_TO_Z_UP.T
    assert np.abs(world_heads(rig, JOINT_NAMES) - expected).max() < 1e-6
    assert expected[:, 2].min() > 0.0  # standing on the floor
    assert all(pb.rotation_mode == "QUATERNION" for pb in rig.pose.bones)

    def z_axis(bone: str) -> np.ndarray:
        return np.array(rig.matrix_world.to_3x3() @ rig.data.bones[bone].matrix_local.to_3x3().col[2])

    assert z_axis("left_elbow") @ (0, 0, 1) > 0.99  # arms: Z up, left and right alike
    assert z_axis("right_elbow") @ (0, 0, 1) > 0.99
    assert z_axis("left_knee") @ (0, -1, 0) > 0.99  # legs: Z toward the front (-Y)

    (body,) = rig.children
    assert body.type == "MESH"
    assert body.modifiers[0].type == "ARMATURE"
    assert body.modifiers[0].object == rig
    assert sorted(g.name for g in body.vertex_groups) == sorted(JOINT_NAMES)
    assert all(len(v.groups) == 1 and v.groups[0].weight == 1.0 for v in body.data.vertices)


# --- keyframes -------------------------------------------------------------------------------------


def test_keyframes_one_per_frame_and_joints_on_the_core_fk(scene, addon):
    from blender_addon import keyframes

    scene.render.fps = 24
    rig = addon.rig.create_rig(bpy.context)
    motion = synthetic_motion(2.0, seed=3)
    action = keyframes.apply_motion(rig, motion, IDENTITY_MAP, "take", 10, 24.0)

    n = 48  # 2 s at the scene's 24 fps
    curves = fcurves_of(action)
    rotated = {fc.data_path.split('"')[1] for fc in curves if fc.data_path.endswith("rotation_quaternion")}
    assert rotated == set(JOINT_NAMES)
    assert [fc.data_path for fc in curves if fc.data_path.endswith("location")] == [
        'pose.bones["pelvis"].location'
    ] * 3
    assert len(curves) == 55 * 4 + 3
    for fc in curves:
        co = np.empty(2 * len(fc.keyframe_points))
        fc.keyframe_points.foreach_get("co", co)
        assert np.array_equal(co[0::2], np.arange(10, 10 + n))

    expected = fk_world(motion.resampled(24.0))
    for f in (0, 1, 17, n - 1):
        scene.frame_set(10 + f)
        assert np.abs(world_heads(rig, JOINT_NAMES) - expected[f]).max() < MM


def test_mixamo_rig_in_a_pose_follows_the_dance(scene, addon):
    from blender_addon import keyframes

    scene.render.fps = 30
    rig = build_armature("Mixamo Dancer", mixamo_rest(prefix="mixamorig1:", scale=0.9))
    names = [b.name for b in rig.data.bones]
    chosen = rigmap.detect(names, rig.name)
    assert chosen.name == "Mixamo"
    mapping, skipped = rigmap.resolve(chosen, names, rig.name)
    assert mapping["pelvis"] == "mixamorig1:Hips"
    assert mapping["left_elbow"] == "mixamorig1:LeftForeArm"
    assert "left_middle1 (mixamorig:LeftHandMiddle1)" in skipped

    motion = synthetic_motion(1.0, seed=5)
    keyframes.apply_motion(rig, motion, mapping, "mixamo take", 1, 30.0)
    assert_dances_like(rig, mapping, motion, 1, scale=0.9)


def test_rigify_deform_bones_are_driven_over_their_constraints(scene, addon, song):
    rigify = rigmap.load_shipped("RIGIFY")
    rig = build_armature("rig", rigify_rest(rigify.bones), mixamo_import=False)
    for bone in rigify.bones.values():
        rig.pose.bones[bone].constraints.new("COPY_TRANSFORMS")  # as Rigify's DEF bones follow ORG bones
    assert generate(scene, song, target="EXISTING", armature=rig) == {"FINISHED"}  # bone map: Auto
    assert all(con.mute for bone in rigify.bones.values() for con in rig.pose.bones[bone].constraints)
    paths = {fc.data_path for fc in fcurves_of(rig.animation_data.action)}
    assert not any("DEF-spine.005" in p or "root" in p for p in paths)  # unmapped bones ride along
    motion = synthetic_motion(2.0, seed=0).resampled(scene.render.fps)  # what the fake generator danced
    assert_dances_like(rig, rigify.bones, motion, scene.frame_start, scale=1.05)


def test_edited_bone_map_in_a_text_block_is_used(scene, addon, song):
    rig = build_armature("Mixamo Dancer", mixamo_rest())
    scene.dancenet.target, scene.dancenet.armature, scene.dancenet.bone_map = "EXISTING", rig, "MIXAMO"
    assert bpy.ops.dancenet.edit_bone_map() == {"FINISHED"}
    text = scene.dancenet.bone_map_text
    assert scene.dancenet.bone_map == "TEXT"
    assert '"mixamorig:Hips"' in text.as_string()
    text.from_string(text.as_string().replace('"left_elbow": "mixamorig:LeftForeArm",', ""))
    with pytest.raises(RuntimeError, match=r"left_elbow \(not in the map\)"):
        generate(scene, song)


def test_missing_bones_are_named(scene, addon, song):
    bones = [b for b in mixamo_rest() if not b[0].endswith(("LeftForeArm", "RightUpLeg"))]
    bones = [(n, "mixamorig:LeftArm" if p == "mixamorig:LeftForeArm" else p, h, t) for n, p, h, t in bones]
    bones = [(n, "mixamorig:Hips" if p == "mixamorig:RightUpLeg" else p, h, t) for n, p, h, t in bones]
    rig = build_armature("Incomplete", bones)
    with pytest.raises(DanceNetError) as err:
        rigmap.resolve(
            rigmap.load_shipped("MIXAMO"), [b.name for b in rig.data.bones], rig.name
        )
    message = str(err.value)
    assert "left_elbow ('mixamorig:LeftForeArm' not in the armature)" in message
    assert "right_hip ('mixamorig:RightUpLeg' not in the armature)" in message

    before = snapshot(scene)
    with pytest.raises(RuntimeError) as report:
        generate(scene, song, target="EXISTING", armature=rig, bone_map="MIXAMO")
    assert "mixamorig:LeftForeArm" in str(report.value)
    assert "Traceback" not in str(report.value)
    before["props"].update(target="EXISTING", armature=str(rig), bone_map="MIXAMO")
    before["props"].update(music_source="FILE", music_file=str(song))
    assert snapshot(scene) == before


def test_shipped_bone_maps_name_known_joints(addon):
    for key in rigmap.SHIPPED:
        bone_map = rigmap.load_shipped(key)
        assert set(bone_map.bones) <= set(JOINT_NAMES)
        assert set(rigmap.REQUIRED_JOINTS) <= set(bone_map.bones)
    assert all(b.startswith("DEF-") for b in rigmap.load_shipped("RIGIFY").bones.values())


def test_a_bad_saved_bone_map_is_left_out_with_a_notice(addon, tmp_path, capsys):
    """One saved map nested thousands deep must not raise RecursionError out of user_maps(), which would break
    Auto for every rig in every file; any file that cannot be read as a map is left out with a notice, and the
    File bone map says what is wrong in one line."""
    saved = tmp_path / "bonemaps"
    saved.mkdir()
    (saved / "good.json").write_text('{"name": "Good", "bones": {"pelvis": "Hips"}}')
    bad = {"deep.json": "[" * 100_000 + "]" * 100_000, "digits.json": '{"bones": ' + "9" * 5000 + "}",
           "binary.json": "\x00\xff", "list.json": "[1, 2]"}
    for name, text in bad.items():
        (saved / name).write_text(text, encoding="latin-1")
    (saved / "folder.json").mkdir()
    capsys.readouterr()
    assert [m.name for m in rigmap.user_maps(saved)] == ["Good"]
    notices = capsys.readouterr().err.strip().splitlines()
    assert sorted(line.split()[4] for line in notices) == sorted([*bad, "folder.json"]), notices
    assert rigmap.detect(list(JOINT_NAMES), "rig", saved).bones  # Auto still works
    for name in ("deep.json", "digits.json"):
        with pytest.raises(DanceNetError) as info:
            rigmap.load_file(saved / name)
        assert "\n" not in str(info.value)


# --- the Generate Dance operator --------------------------------------------------------------------


def test_generate_builds_rig_strip_markers_and_keeps_earlier_takes(scene, addon, song):
    assert generate(scene, song, seed=7) == {"FINISHED"}
    rig = bpy.data.objects["DanceNet Dancer"]
    first = rig.animation_data.action
    assert first.name == "Test Song · hiphop · seed 7"
    assert first.use_fake_user
    (strip,) = scene.sequence_editor.strips_all
    assert strip.type == "SOUND"
    assert Path(bpy.path.abspath(strip.sound.filepath)) == song
    assert (scene.frame_start, scene.frame_end) == (1, 48)
    assert [(m.name, m.frame) for m in sorted(scene.timeline_markers, key=lambda m: m.frame)] == [
        ("bar 1", 1), ("·", 13), ("·", 25), ("·", 37),
    ]  # fmt: skip
    props = scene.dancenet
    assert (props.target, props.armature) == ("EXISTING", rig)
    label = bpy.types.UILayout.enum_item_name
    assert label(props, "style", "auto") == "Auto (Hiphop)"
    assert label(props, "style", "hiphop") == "Hiphop  70%"

    def values(action) -> np.ndarray:
        out = []
        for fc in fcurves_of(action):
            co = np.empty(2 * len(fc.keyframe_points))
            fc.keyframe_points.foreach_get("co", co)
            out.append(co)
        return np.concatenate(out)

    kept = values(first)
    assert generate(scene, song, seed=8, style="jazz") == {"FINISHED"}
    second = rig.animation_data.action
    assert second.name == "Test Song · jazz · seed 8"
    assert second != first
    assert np.array_equal(values(bpy.data.actions["Test Song · hiphop · seed 7"]), kept)
    assert len(scene.sequence_editor.strips_all) == 1  # the song's strip is reused, not doubled
    assert len([o for o in bpy.data.objects if o.type == "ARMATURE"]) == 1


def test_takes_become_separate_actions(scene, addon, song):
    assert generate(scene, song, takes=3) == {"FINISHED"}
    names = sorted(a.name for a in bpy.data.actions)
    assert names == [f"Test Song · hiphop · seed 0 · take {k}" for k in (1, 2, 3)]
    assert bpy.data.objects["DanceNet Dancer"].animation_data.action.name.endswith("take 1")


@pytest.mark.skipif(os.name != "posix" or sys.platform == "darwin", reason="a name that is not UTF-8 needs a file "
                    "system that stores bytes")
def test_a_song_whose_name_is_not_utf8_is_one_line(scene, addon, song, capsys):
    """A Latin-1 `caf\\xe9.wav` from an old archive: Blender's strips and names take UTF-8 only, so Generate
    Dance says to rename it, naming it (the byte that is not UTF-8 as U+FFFD), before any work."""
    latin1 = song.rename(song.with_name(os.fsdecode(b"caf\xe9.wav")))
    with pytest.raises(RuntimeError, match="rename 'caf\ufffd.wav'"):
        generate(scene, latin1)
    assert not bpy.data.actions and not bpy.data.sounds


def test_an_empty_sequencer_is_read_through_strips(scene, addon):
    """Blender 5.0 has only `strips`, and an empty collection is falsy: it must not fall back to `sequences`."""
    scene.sequence_editor_create()
    assert addon.song.strips_of(scene).path_from_id() == "sequence_editor.strips"


def test_active_sound_strip_is_the_music_source(scene, addon, song):
    scene.sequence_editor_create()
    strip = scene.sequence_editor.strips.new_sound("song", str(song), 2, 30)
    scene.sequence_editor.active_strip = strip
    scene.dancenet.music_source = "STRIP"
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (30, 77)
    assert len(scene.sequence_editor.strips_all) == 1


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"music_file": ""}, "No audio file chosen"),
        ({"music_file": "/nonexistent/song.wav"}, "Audio file not found"),
        ({"music_file": "NOTES"}, "is not an audio file"),
        ({"music_source": "STRIP"}, "No active sound strip"),
        ({"target": "EXISTING"}, "No target armature"),
        (
            {"target": "EXISTING", "armature": "RIG", "bone_map": "TEXT", "bone_map_text": "BAD"},
            "not valid JSON",
        ),
    ],
)
def test_bad_inputs_are_reported_not_raised(scene, addon, tmp_path, settings, message):
    props = scene.dancenet
    if settings.get("music_file") == "NOTES":
        settings["music_file"] = str(tmp_path / "notes.txt")
        Path(settings["music_file"]).write_text("not a song")
    if settings.get("armature") == "RIG":
        settings["armature"] = addon.rig.create_rig(bpy.context, with_mesh=False)
    if settings.get("bone_map_text") == "BAD":
        settings["bone_map_text"] = bpy.data.texts.new("map.json")
        settings["bone_map_text"].write('{"bones": {"pelvis": ')
    props.music_file = str(write_song(tmp_path / "ok.wav", 1.0))
    for key, value in settings.items():
        setattr(props, key, value)
    before = snapshot(scene)
    with pytest.raises(RuntimeError) as report:  # bpy.ops turns an operator's ERROR report into this
        bpy.ops.dancenet.generate()
    assert str(report.value).startswith("Error: ")
    assert message in str(report.value)
    assert "Traceback" not in str(report.value)
    assert snapshot(scene) == before


def test_background_generation_cancelled_with_esc_changes_nothing(scene, addon, song, monkeypatch):
    monkeypatch.setattr(
        addon.pipeline, "load_generator", lambda: make_fake_generator(step_delay=0.05, steps=400)
    )
    scene.dancenet.music_file = str(song)
    before = snapshot(scene)
    op = modal_stand_in(addon.operators.DANCENET_OT_generate)
    op._begin(bpy.context, addon.pipeline.prepare(scene))
    deadline = time.monotonic() + 10
    while op._job.progress()[1] == 0.0 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert op.modal(bpy.context, SimpleNamespace(type="TIMER")) == {"PASS_THROUGH"}
    runtime = bpy.context.window_manager.dancenet
    assert runtime.running
    assert runtime.stage == "dancing"
    assert runtime.progress > 0
    assert op.modal(bpy.context, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    op._job.join(5)
    assert op._job.done
    assert isinstance(op._job.error, GenerationCancelled)
    assert not runtime.running
    assert op.reports == [({"WARNING"}, "DanceNet: cancelled; nothing was changed")]
    assert snapshot(scene) == before


def test_background_generation_runs_to_the_end(scene, addon, song):
    scene.dancenet.music_file = str(song)
    op = modal_stand_in(addon.operators.DANCENET_OT_generate)
    op._begin(bpy.context, addon.pipeline.prepare(scene))
    op._job.join(30)
    assert op.modal(bpy.context, SimpleNamespace(type="TIMER")) == {"FINISHED"}
    assert op.reports[0][0] == {"INFO"}
    assert "DanceNet Dancer" in op.reports[0][1]
    assert bpy.data.objects["DanceNet Dancer"].animation_data.action is not None


def test_file_saved_mid_generation_does_not_load_busy(scene, addon, tmp_path):
    bpy.context.window_manager.dancenet.running = True
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "busy.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "busy.blend"))
    assert not bpy.context.window_manager.dancenet.running


def test_generator_errors_are_reported(scene, addon, song, monkeypatch):
    def failing(_request, **_kwargs):
        raise DanceNetError("could not decode the song")

    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: failing)
    before = snapshot(scene)
    with pytest.raises(RuntimeError, match="could not decode the song"):
        generate(scene, song)
    before["props"].update(music_source="FILE", music_file=str(song))
    assert snapshot(scene) == before


@pytest.mark.parametrize("target", ["NEW", "EXISTING"])
def test_panel_draws_every_setting(scene, addon, song, target):
    shot = panel_screenshot()
    generate(scene, song)  # a rig with a dance, an analysis to show
    scene.dancenet.target = target
    for panel in addon.panels.MAIN_PANELS:  # each with its sub-panels
        root = shot.record_panel(bpy.context, panel)
        shown = {w.text: w for w in shot.walk(root)}
        assert {
            "File", "Sound Strip", "Style", "Seed", "Temperature", "Takes", "Foot Clean-up", "Beat Markers",
            "New Rig", "Existing Armature", "Generate Dance", "Export FBX", "Export BVH",
        } <= set(shown)  # fmt: skip
        assert [w.value for w in shot.walk(root) if w.kind == "text"] == [str(song)]
        assert shown["Style"].value == "Auto (Hiphop)"
        assert shown["Hiphop 70%"].kind == "progress"
        assert shown["Temperature"].value == "1.00"
        assert shown["Foot Clean-up"].selected
        assert shown["Generate Dance"].enabled
        assert shown["Generate Dance"].kind == "operator"
        assert shown["Existing Armature"].selected == (target == "EXISTING")
        assert ("Bone Map" in shown) == (target == "EXISTING") == ("Mannequin" not in shown)
    image = shot.paint(root)
    assert image.width == shot.WIDTH + shot.TAB_WIDTH
    assert image.height > 20 * shot.UNIT


# --- exports ---------------------------------------------------------------------------------------


def test_bvh_and_fbx_reimport_with_the_same_motion(scene, addon, song, tmp_path):
    generate(scene, song)
    rig = bpy.data.objects["DanceNet Dancer"]
    assert bpy.ops.dancenet.export_bvh(filepath=str(tmp_path / "d.bvh")) == {"FINISHED"}
    assert bpy.ops.dancenet.export_fbx(filepath=str(tmp_path / "d.fbx")) == {"FINISHED"}
    assert "OFFSET 0.000000 0.950000 0.000000" in (tmp_path / "d.bvh").read_text()[:200]  # Y up, metres

    frames = (scene.frame_start, scene.frame_start + 20, scene.frame_end)
    reference = {}
    for f in frames:
        scene.frame_set(f)
        reference[f] = world_heads(rig, JOINT_NAMES)

    def imported(op, **kwargs):
        before = set(bpy.data.objects)
        op(**kwargs)
        return next(o for o in set(bpy.data.objects) - before if o.type == "ARMATURE")

    bvh = imported(bpy.ops.import_anim.bvh, filepath=str(tmp_path / "d.bvh"), frame_start=scene.frame_start)
    fbx = imported(bpy.ops.import_scene.fbx, filepath=str(tmp_path / "d.fbx"))
    for f in frames:
        scene.frame_set(f)
        assert np.abs(world_heads(bvh, JOINT_NAMES) - reference[f]).max() < MM
        scene.frame_set(f + 1)  # Blender's FBX importer starts the animation one frame later
        assert np.abs(world_heads(fbx, JOINT_NAMES) - reference[f]).max() < MM


# --- batch mode ------------------------------------------------------------------------------------


def test_batch_writes_one_folder_per_song_and_fails_the_bad_one(addon, tmp_path, capsys):
    from blender_addon import batch

    good = write_song(tmp_path / "good.wav", 1.0)
    code = batch.main(
        [
            str(good),
            str(tmp_path / "missing.wav"),
            "--out",
            str(tmp_path / "out"),
            "--bvh",
            "--fbx",
            "--takes",
            "2",
        ],
        generator=make_fake_generator(),
    )
    lines = capsys.readouterr().out.splitlines()  # among the exporters' own chatter
    out = [line for line in lines if line.startswith(("OK ", "FAILED ")) or line.endswith("songs done")]
    assert code == 1
    assert out[0].startswith("OK      good.wav: hiphop, 1.0 s, 2 takes")
    assert out[1].startswith("FAILED  missing.wav: song not found")
    assert out[2] == "1 of 2 songs done"
    assert {p.name for p in (tmp_path / "out" / "good").iterdir()} == {"good.blend", "good.bvh", "good.fbx"}


def test_batch_renders_a_preview_video(addon, tmp_path, capsys):
    from blender_addon import batch

    song = write_song(tmp_path / "short.wav", 0.5)
    code = batch.main(
        [str(song), "--out", str(tmp_path), "--render", "--resolution", "96x64"],
        generator=make_fake_generator(),
    )
    assert code == 0, capsys.readouterr().out
    meta, frames = read_video(tmp_path / "short" / "short.mp4")
    # the take at the dance's 30 fps, 0.5 s of it, at the size asked for, with the song, the figure moving
    assert (meta["size"], meta["fps"], meta["audio_codec"], frames.shape) == ((96, 64), 30, "aac", (15, 64, 96, 3))
    assert (np.abs(np.diff(frames.astype(np.int16), axis=0)).max(axis=(1, 2, 3)) > 40).all()
    assert (frames.std(axis=(1, 2, 3)) > 10).all()  # never a blank frame
    assert bpy.context.scene.render.engine == "BLENDER_WORKBENCH"


def test_batch_skips_what_it_did_before_and_force_dances_it_again(addon, tmp_path, capsys):
    from blender_addon import batch

    song = write_song(tmp_path / "again.wav", 0.5)
    args = [str(song), "--out", str(tmp_path / "out"), "--bvh"]
    assert batch.main(args, generator=make_fake_generator()) == 0
    blend = tmp_path / "out" / "again" / "again.blend"
    made = blend.stat().st_mtime_ns
    capsys.readouterr()
    assert batch.main(args, generator=make_fake_generator()) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("SKIPPED again.wav: done before") and lines[-1] == "1 of 1 songs done", lines
    assert blend.stat().st_mtime_ns == made
    assert batch.main([*args, "--seed", "2"], generator=make_fake_generator()) == 0  # another request
    assert capsys.readouterr().out.startswith("OK      again.wav")
    assert batch.main([*args, "--seed", "2", "--force"], generator=make_fake_generator()) == 0
    assert capsys.readouterr().out.startswith("OK      again.wav")


def _run_python(code: str, tmp_path: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {**os.environ, **BLENDER_ENV, "HOME": str(tmp_path / "home"), "PYTHONPATH": str(ROOT / "tests" / "addon")}
    return subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout
    )


def test_batch_command_line_exits_non_zero_on_failure(tmp_path):
    env = {**os.environ, **BLENDER_ENV, "HOME": str(tmp_path / "home")}
    run = subprocess.run(
        [sys.executable, "blender_addon/batch.py", str(tmp_path / "nope.wav"), "--out", str(tmp_path)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert run.returncode == 1, run.stderr
    assert "FAILED  nope.wav: song not found" in run.stdout
    assert "Traceback" not in run.stderr


# --- never lose a user's work -----------------------------------------------------------------------


def test_generate_keeps_the_users_own_action_and_says_so(scene, addon, song, tmp_path):
    rig = addon.rig.create_rig(bpy.context, "My Rig", with_mesh=False)
    rig.animation_data_create()
    mine = bpy.data.actions.new("My Walk")
    rig.animation_data.action = mine
    rig.pose.bones["pelvis"].location = (0.0, 0.1, 0.0)
    rig.pose.bones["pelvis"].keyframe_insert("location", frame=1)
    assert not mine.use_fake_user
    scene.dancenet.music_source, scene.dancenet.music_file = "FILE", str(song)
    scene.dancenet.target, scene.dancenet.armature = "EXISTING", rig
    applied = addon.pipeline.generate_now(bpy.context, addon.pipeline.prepare(scene), make_fake_generator())
    assert rig.animation_data.action.name != "My Walk"
    assert "your action 'My Walk' was kept" in applied.summary()
    blend = tmp_path / "saved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    assert "My Walk" in bpy.data.actions  # before: 0 users, gone after save and reopen
    # a second Generate on the same rig replaces our take, and adds no note about it
    scene = bpy.context.scene
    applied = addon.pipeline.generate_now(bpy.context, addon.pipeline.prepare(scene), make_fake_generator())
    assert "your action" not in applied.summary()


def test_generate_removes_only_its_own_markers(scene, addon, song):
    scene.timeline_markers.new("bar 2", frame=13)  # the user's, named like ours
    scene.timeline_markers.new("chorus", frame=30)
    assert generate(scene, song, seed=1) == {"FINISHED"}
    assert generate(scene, song, seed=2) == {"FINISHED"}
    markers = sorted((m.name, m.frame) for m in scene.timeline_markers)
    assert ("bar 2", 13) in markers
    assert ("chorus", 30) in markers
    assert markers.count(("bar 1", 1)) == 1  # ours replaced, not doubled


def test_batch_gives_colliding_songs_their_own_folders_inside_out(addon, tmp_path, capsys):
    from blender_addon import batch

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    songs = [write_song(tmp_path / "a" / "song.wav", 0.5), write_song(tmp_path / "b" / "song.wav", 0.5),
             write_song(tmp_path / "...wav", 0.5)]
    out = tmp_path / "nested" / "out"
    (out / "song").mkdir(parents=True)
    (out / "song" / "song.blend").write_bytes(b"the user's earlier result")
    code = batch.main([*map(str, songs), "--out", str(out), "--bvh"], generator=make_fake_generator())
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith(("OK ", "FAILED "))]
    assert code == 0, lines
    assert len(lines) == 3, lines
    assert (out / "song" / "song.blend").read_bytes() == b"the user's earlier result"
    folders = sorted(p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert folders == ["song", "song_2", "song_3", "song_4"], folders
    assert {p.name for p in out.iterdir() if p.is_file()} == {"batch.csv", "batch.json"}
    assert {p.name for p in (out / "song_2").iterdir()} == {"song_2.blend", "song_2.bvh"}
    assert sorted(p.name for p in (tmp_path / "nested").iterdir()) == ["out"]  # nothing written beside --out
    assert f"-> {out / 'song_2'} " in lines[0]
    assert f"-> {out / 'song_3'} " in lines[1]
