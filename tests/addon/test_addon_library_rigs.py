"""In the add-on, a motion library from rigs, not only from BVH files. A Mixamo-named armature resting
in an A-pose (and DanceNet's own rig in its T-pose) is keyed with a known dance by the add-on's own keying; then
(i) its action, as one of the file's armature actions, (ii) the rig exported to FBX in a Library folder beside a
BVH clip, are built into a library whose clip reproduces the keyed joint positions, and Generate Dance with the
library engine keys a rig from it; (iii) a non-humanoid armature's action, an FBX file without an armature and a
0.5-s action are answered in one line. The file is left as it was by every build: the user's objects, actions,
scenes and data blocks, the rig's action and pose, the scene's frame."""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from doubles import mixamo_rest, synthetic_motion, write_song
from scene_helpers import IDENTITY_MAP, bpy, build_armature, fcurves_of, generate, modal_stand_in, panel_screenshot

from dancenet_core.bvh import write_bvh
from dancenet_core.generate import generate_dance
from dancenet_core.library.store import MotionLibrary, built_path, library_path
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

FPS = 25
# How near the library's clip comes to the keyed dance, joint by joint about the pelvis and along the pelvis' path
# over the floor (metres). Measured: 0.27 mm from the action and through FBX alike (bpy 4.5 and 5.2.3); 2 mm leaves
# a margin, while an A-pose read as a T-pose misses by 10 cm and more (tests/library/test_armature_clips.py).
TOLERANCE_M = 2e-3
TIMINGS: dict[str, float] = {}  # what each build took (pytest -s prints them with the errors)


def _dance(seconds: float, seed: int = 1) -> Motion:
    """Legs and arms swinging a cycle every two beats at 110 BPM (beats the library can cut on), over smaller turns
    of every body joint, the pelvis walking forward and bobbing."""
    motion = synthetic_motion(seconds, seed, fps=FPS)
    t = np.arange(motion.num_frames) / FPS
    s = np.sin(np.pi * 110 / 60 * t)
    rot = np.zeros_like(motion.rotations)
    rot[:, 1:BODY_JOINTS] = 0.3 * motion.rotations[:, 1:BODY_JOINTS]
    rot[:, JOINT_INDEX["left_hip"], 0] += 0.5 * s
    rot[:, JOINT_INDEX["right_hip"], 0] -= 0.5 * s
    rot[:, JOINT_INDEX["left_shoulder"], 2] += -1.2 + 0.4 * s
    rot[:, JOINT_INDEX["right_shoulder"], 2] += 1.2 + 0.4 * s
    root = np.stack([0.05 * s, 0.9 + 0.02 * np.cos(2 * np.pi * 110 / 60 * t), 0.3 * t], axis=1)
    return Motion(rot, root, FPS)


def _keyed_rig(addon, kind: str, action: str, seconds: float = 12.0) -> tuple[bpy.types.Object, Motion, float]:
    """(a rig keyed with a known dance by the add-on's keying, the dance, the rig's size against ours)."""
    from blender_addon import keyframes

    if kind == "mixamo":  # A-pose, Y-up centimetres under a 0.01 object scale, 0.9 of our size
        rig, scale = build_armature("Mixamo Dancer", mixamo_rest(scale=0.9, a_pose_deg=40.0)), 0.9
        mapping = addon.rigchoice.resolve_map(rig, None)[0]
    else:  # DanceNet's own rig, in our T-pose
        rig, scale = addon.rig.create_rig(bpy.context, "Own Dancer", with_mesh=False), 1.0
        mapping = IDENTITY_MAP
    motion = _dance(seconds)
    keyframes.apply_motion(rig, motion, mapping, action, 1, None)
    return rig, motion, scale


def _position_error(clip: Motion, motion: Motion, scale: float) -> float:
    """Largest distance (m) between the clip's body joints and the keyed dance's (scaled to the rig), about the
    pelvis and along the pelvis' path over the floor (the clip is put on the floor, so heights differ by it)."""
    got, want = clip.positions()[:, :BODY_JOINTS], scale * motion.positions()[:, :BODY_JOINTS]
    assert len(got) == len(want)
    about = np.linalg.norm((got - got[:, :1]) - (want - want[:, :1]), axis=-1).max()
    path = got[:, 0, [0, 2]] - got[0, 0, [0, 2]] - (want[:, 0, [0, 2]] - want[0, 0, [0, 2]])
    return float(max(about, np.linalg.norm(path, axis=-1).max()))


def _data_counts() -> dict[str, int]:
    return {kind: len(getattr(bpy.data, kind)) for kind in dir(bpy.data)
            if isinstance(getattr(bpy.data, kind, None), bpy.types.bpy_prop_collection)}


def _rig_state(scene, rig) -> tuple:
    anim = rig.animation_data
    return (scene.frame_current, anim.action.name if anim and anim.action else None,
            tuple(round(v, 6) for pb in rig.pose.bones for v in (*pb.location, *pb.rotation_quaternion)),
            tuple(round(v, 6) for pb in rig.pose.bones for row in pb.matrix for v in row))


@pytest.fixture
def own_cache(monkeypatch, tmp_path) -> Path:
    """A cache of this test's own: a library built by another test (or run) must not read as built here."""
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture
def real(addon, scene, monkeypatch, tmp_path):
    """The core's generate_dance in place of the fake generator; a 6-s song at 120 BPM; the scene at 25 fps."""
    monkeypatch.setattr(addon.pipeline, "load_generator", lambda: generate_dance)
    scene.render.fps = FPS
    return write_song(tmp_path / "Rig Library Song.wav", 6.0)


def _row() -> list[tuple[str, str]]:
    """The Dance panel's Build Library button and what it says beside it."""
    shot = panel_screenshot()
    widgets = shot.walk(shot.record_panel(bpy.context))
    k = next((i for i, w in enumerate(widgets) if w.text == "Build Library"), None)
    return [] if k is None else [(w.text, w.icon) for w in widgets[k : k + 2]]


@pytest.mark.parametrize("kind", ["mixamo", "own"])
def test_a_library_from_the_files_actions_then_a_dance_from_it(scene, addon, real, own_cache, kind):
    rig, motion, scale = _keyed_rig(addon, kind, "salsa_basic")
    rig.pose.bones[0].location = (0.01, 0.0, 0.0)  # the user's own pose on a bone: kept too
    scene.frame_set(7)
    props = scene.dancenet
    props.engine, props.library_source = "library", "ACTIONS"
    assert _row() == [("Build Library", "FILE_REFRESH"), ("1 action, not built yet", "INFO")]
    counts, state = _data_counts(), _rig_state(scene, rig)
    t = time.perf_counter()
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    TIMINGS[f"actions, {kind}"] = time.perf_counter() - t
    assert _data_counts() == counts and _rig_state(scene, rig) == state  # nothing in the file changed
    assert _row()[1] == ("1 action, built", "CHECKMARK")
    built = addon.library.chosen_library(props)
    library = MotionLibrary.load(built)
    assert library.names == ["salsa_basic"] and library.styles == ["salsa"]
    error = _position_error(library.clip(0), motion, scale)
    print(f"actions, {kind} rig: largest joint error {error * 1000:.3f} mm, build {TIMINGS[f'actions, {kind}']:.2f} s")
    assert error < TOLERANCE_M

    props.target, props.armature = "EXISTING", rig
    assert generate(scene, real, engine="library", style="salsa") == {"FINISHED"}
    take = rig.animation_data.action
    assert take.name != "salsa_basic" and addon.takes.take_info(take)["library"] == str(built)
    dance = addon.takes.take_motion(take)
    assert dance.num_frames >= 6 * FPS - 2
    assert np.ptp(dance.rotations[:, JOINT_INDEX["left_hip"]], axis=0).max() > 0.3  # the clip's swing, danced
    assert _row()[1] == ("1 action, built", "CHECKMARK")  # a take is no clip: still built
    fcurves_of(bpy.data.actions["salsa_basic"])[0].keyframe_points.insert(400, 0.0)
    assert _row()[1] == ("1 action, not built yet", "INFO")  # a key more: another content


def _export_fbx(rig, path: Path) -> None:
    """The rig and its action, as Blender's FBX exporter writes them (only the action that plays, over the scene's
    frame range: the action's)."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = (round(f) for f in rig.animation_data.action.frame_range)
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.export_scene.fbx(filepath=str(path), use_selection=True, object_types={"ARMATURE"}, add_leaf_bones=False,
                             bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                             bake_anim_simplify_factor=0.0)  # every key as keyed (simplified, feet move by 6 mm)


def test_a_library_folder_with_an_fbx_file(scene, addon, real, own_cache, tmp_path):
    rig, motion, scale = _keyed_rig(addon, "mixamo", "Samba")
    folder = tmp_path / "clips"
    (folder / "samba").mkdir(parents=True)
    _export_fbx(rig, folder / "samba" / "Samba Dancing.fbx")
    other = _dance(12.0, seed=4)  # a BVH clip of the rig's size: the library's skeleton, the clips' mean, is it
    write_bvh(folder / "samba" / "swing.bvh", Motion(other.rotations, other.root_positions * scale, FPS,
                                                     DEFAULT_SKELETON.scaled(scale)))
    props = scene.dancenet
    props.engine, props.library = "library", str(folder)
    counts, state = _data_counts(), _rig_state(scene, rig)
    t = time.perf_counter()
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    TIMINGS["fbx folder"] = time.perf_counter() - t
    assert _data_counts() == counts and _rig_state(scene, rig) == state  # the import went, all of it
    library = MotionLibrary.load(library_path(folder))
    assert library.names == ["samba/Samba Dancing.fbx", "samba/swing.bvh"] and library.styles == ["samba"] * 2
    error = _position_error(library.clip(0), motion, scale)
    print(f"FBX: largest joint error {error * 1000:.3f} mm, build {TIMINGS['fbx folder']:.2f} s")
    assert error < TOLERANCE_M
    assert generate(scene, real, engine="library", library=str(folder)) == {"FINISHED"}
    assert bpy.data.objects["DanceNet Dancer"].animation_data.action is not None


def test_build_library_samples_in_the_background_and_esc_stops_it(scene, addon, own_cache):
    """The actions are sampled a step per timer tick (the status bar moves, Esc is heard between them)."""
    rig, _motion, _scale = _keyed_rig(addon, "mixamo", "waltz_box", seconds=4.0)
    rig.animation_data.action = None
    other = _dance(4.0, seed=2)
    from blender_addon import keyframes

    keyframes.apply_motion(rig, other, addon.rigchoice.resolve_map(rig, None)[0], "waltz_turn", 1, None)
    props = scene.dancenet
    props.engine, props.library_source = "library", "ACTIONS"
    counts = _data_counts()
    op = modal_stand_in(addon.operators.DANCENET_OT_build_library)
    op._begin(bpy.context, addon.library.build_job(props))
    tick = SimpleNamespace(type="TIMER")
    assert op.modal(bpy.context, tick) == {"PASS_THROUGH"}  # the first action sampled
    assert bpy.context.window_manager.dancenet.stage == "sampling waltz_box"
    assert op.modal(bpy.context, SimpleNamespace(type="ESC")) == {"CANCELLED"}
    assert op.reports == [({"WARNING"}, "DanceNet: cancelled; nothing was changed")]
    assert _data_counts() == counts and not addon.library.chosen_library(props).is_file()

    op = modal_stand_in(addon.operators.DANCENET_OT_build_library)
    op._begin(bpy.context, addon.library.build_job(props))
    for _ in range(600):
        result = op.modal(bpy.context, tick)
        if result != {"PASS_THROUGH"}:
            break
        op._job.join(0.05)
    assert result == {"FINISHED"}
    assert op.reports == [({"INFO"}, "Built library: 2 clips, 0.1 min, styles waltz")]


def _snake() -> bpy.types.Object:
    """An armature of three bones in a row, with an action that wiggles them."""
    from blender_addon.rig import armature_from_rows

    rows = [("a", None, (0, 0, 0), (0, 0, 1)), ("b", "a", (0, 0, 1), (0, 0, 2)), ("c", "b", (0, 0, 2), (0, 0, 3))]
    snake = armature_from_rows(bpy.context, "Snake", rows, {r[0]: np.array([1.0, 0, 0]) for r in rows})
    snake.animation_data_create().action = bpy.data.actions.new("snake_wiggle")
    for frame, angle in ((1, 0.0), (50, 0.5)):
        snake.pose.bones["b"].rotation_quaternion = (np.cos(angle), np.sin(angle), 0.0, 0.0)
        snake.pose.bones["b"].keyframe_insert("rotation_quaternion", frame=frame)
    return snake


def test_bad_actions_and_files_are_one_line(scene, addon, own_cache, tmp_path):
    scene.render.fps = FPS
    _snake()
    _keyed_rig(addon, "mixamo", "blip", seconds=0.5)
    props = scene.dancenet
    props.engine, props.library_source = "library", "ACTIONS"
    counts = _data_counts()
    with pytest.raises(RuntimeError) as report:
        bpy.ops.dancenet.build_library()
    text = str(report.value).strip()
    assert len(text.splitlines()) == 1 and "Traceback" not in text, text
    assert text == "Error: none of the 1 actions could be read: blip: 0.48 s, too short to hold a bar", text
    assert _data_counts() == counts

    good, _motion, _scale = _keyed_rig(addon, "own", "hustle_one")
    good.animation_data.action = None
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    library = MotionLibrary.load(addon.library.chosen_library(props))
    assert library.names == ["hustle_one"]
    snake, blip = library.notes
    assert snake == ("left out snake_wiggle: armature 'Snake': not a humanoid skeleton (3 bones: a, b, c): no legs; "
                     "no arms; no bone for pelvis, neck, head"), snake
    assert blip == "left out blip: 0.48 s, too short to hold a bar"

    # A Library folder: an FBX file with a mesh and no armature, beside a BVH clip; then that FBX alone.
    folder = tmp_path / "folder"
    folder.mkdir()
    bpy.ops.mesh.primitive_cube_add()
    bpy.ops.export_scene.fbx(filepath=str(folder / "Cube.fbx"), use_selection=True)
    bpy.data.objects.remove(bpy.context.active_object)
    props.library_source, props.library = "FOLDER", str(folder)
    counts = _data_counts()
    with pytest.raises(RuntimeError) as report:
        bpy.ops.dancenet.build_library()
    text = str(report.value).strip()
    assert text == f"Error: none of the 1 clips in {folder} could be read: Cube.fbx: no armature in it", text
    write_bvh(folder / "clip.bvh", _dance(12.0))
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    assert MotionLibrary.load(library_path(folder)).notes == ("left out Cube.fbx: no armature in it",)
    (folder / "broken.fbx").write_text("these are my notes, not an FBX file\n")
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    broken = MotionLibrary.load(library_path(folder)).notes[1]
    assert broken.startswith("left out broken.fbx: Blender could not import it (") and "\n" not in broken, broken
    assert _data_counts() == counts


def test_generate_asks_to_build_the_actions_library_first(scene, addon, real, own_cache):
    _keyed_rig(addon, "own", "rumba_walk", seconds=4.0)
    props = scene.dancenet
    props.library_source = "ACTIONS"
    with pytest.raises(RuntimeError, match="The library of this file's armature actions is not built .or they "
                                           "changed since.: press Build Library first"):
        generate(scene, real, engine="library")
    assert not built_path("none").is_file()



def test_an_actions_tempo_and_meter_properties_are_taken(scene, addon, own_cache):
    """An action's `dancenet_bpm` and `dancenet_meter` are the clip's tempo and meter in the library (as a folder's
    manifest.csv columns); one that is no tempo leaves the action out in one line."""
    scene.render.fps = FPS
    rig, _motion, _scale = _keyed_rig(addon, "own", "rumba_told", seconds=12.0)
    action = rig.animation_data.action
    action["dancenet_bpm"], action["dancenet_meter"] = 100.0, 3
    props = scene.dancenet
    props.engine, props.library_source = "library", "ACTIONS"
    assert bpy.ops.dancenet.build_library() == {"FINISHED"}
    library = MotionLibrary.load(addon.library.chosen_library(props))
    assert library.meter.tolist() == [3] and library.tempo_bpm.tolist() == [100.0]
    assert library.source == ["tempo: manifest, meter: manifest"]

    action["dancenet_meter"] = 5
    with pytest.raises(RuntimeError) as report:
        bpy.ops.dancenet.build_library()
    text = str(report.value).strip()
    assert text == ("Error: no action animates a humanoid armature in this file: rumba_told: its dancenet_meter 5 is "
                    "not beats per bar (2, 3, 4 or 6); correct it or delete the property"), text
