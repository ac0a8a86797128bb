"""A failed Generate Dance leaves the file as it was: refused up front where it can be
checked, and put back whatever step of applying the dance fails."""

from __future__ import annotations

import pytest
from doubles import make_fake_generator
from scene_helpers import bpy, generate, panel_screenshot, snapshot


def rig_state(rig) -> dict:
    """What applying a dance may change on a rig: its animation, pose, constraints, selection."""
    anim = rig.animation_data
    return {
        "action": anim.action.name if anim is not None and anim.action is not None else None,
        "tracks": [(t.name, t.mute) for t in anim.nla_tracks] if anim is not None else None,
        "pose": {pb.name: (pb.rotation_mode, tuple(pb.location), tuple(pb.rotation_quaternion),
                           tuple(pb.rotation_euler), tuple(pb.scale), [c.mute for c in pb.constraints])
                 for pb in rig.pose.bones},
        "fake users": {a.name: a.use_fake_user for a in bpy.data.actions},
        "selected": sorted(o.name for o in bpy.context.selected_objects),
        "active": getattr(bpy.context.view_layer.objects.active, "name", None),
    }


def users_rig(addon):
    """A rig with the user's own keyed action, NLA track, a constraint and a bone posed by hand (unkeyed)."""
    rig = addon.rig.create_rig(bpy.context, "Hero", with_mesh=False)
    anim = rig.animation_data_create()
    anim.action = bpy.data.actions.new("hero idle")
    rig.pose.bones["head"].rotation_quaternion = (0.9, 0.1, 0.0, 0.0)
    rig.keyframe_insert('pose.bones["head"].rotation_quaternion', frame=1)
    track = anim.nla_tracks.new()
    track.name = "hero layer"
    track.strips.new("wave", 5, bpy.data.actions.new("hero wave"))
    rig.pose.bones["left_elbow"].constraints.new("COPY_ROTATION")
    rig.pose.bones["left_wrist"].rotation_quaternion = (0.8, 0.0, 0.6, 0.0)
    return rig


def test_a_rig_with_zero_scale_is_refused_in_one_line_before_anything_changes(scene, addon, song):
    rig = users_rig(addon)
    rig.scale = (0.0, 0.0, 0.0)
    scene.timeline_markers.new("chorus", frame=30)
    before, rig_before = snapshot(scene), rig_state(rig)
    with pytest.raises(RuntimeError) as report:
        generate(scene, song, target="EXISTING", armature=rig)
    message = str(report.value).strip()
    assert "Armature 'Hero' has a zero scale (0, 0, 0" in message
    assert "Traceback" not in message and "LinAlgError" not in message
    before["props"].update(music_source="FILE", music_file=str(song), target="EXISTING", armature=str(rig))
    assert snapshot(scene) == before
    assert rig_state(rig) == rig_before


def test_a_rig_flattened_while_the_dance_is_made_changes_nothing(scene, addon, song):
    """Checked again when the result is applied: the rig may change during the minutes of generation."""
    rig = users_rig(addon)
    props = scene.dancenet
    props.music_source, props.music_file, props.target, props.armature = "FILE", str(song), "EXISTING", rig
    plan = addon.pipeline.prepare(scene)
    result = make_fake_generator()(plan.request)
    rig.scale = (1.0, 0.0, 1.0)
    bpy.context.view_layer.update()  # as Blender does after an edit in its interface
    before, rig_before = snapshot(scene), rig_state(rig)
    with pytest.raises(addon.pipeline.DanceNetError, match="zero scale.*nothing was changed"):
        addon.pipeline.apply_result(bpy.context, plan, result)
    assert snapshot(scene) == before
    assert rig_state(rig) == rig_before


class Injected(Exception):
    pass


def _fail_after(function, calls: int = 1):
    """`function`, raising (after doing its work) on its `calls`-th call: a failure half-way through applying."""
    count = [0]

    def wrapped(*args, **kwargs):
        out = function(*args, **kwargs)
        count[0] += 1
        if count[0] >= calls:
            raise Injected("injected failure")
        return out

    return wrapped


_STEPS = ["song strip", "new rig", "second take", "markers", "panel settings"]


@pytest.mark.parametrize("target", ["NEW", "EXISTING"])
@pytest.mark.parametrize("step", _STEPS)
def test_a_failure_at_any_step_of_applying_leaves_the_file_as_it_was(scene, addon, song, monkeypatch, target, step):
    from blender_addon import keyframes, markers, pipeline, properties
    from blender_addon import song as song_strips

    if step == "new rig" and target == "EXISTING":
        pytest.skip("an existing rig is used, none is built")
    rig = users_rig(addon) if target == "EXISTING" else None
    other = bpy.data.objects.new("Lamp post", None)
    scene.collection.objects.link(other)
    for obj in scene.objects:
        obj.select_set(obj == other)
    bpy.context.view_layer.objects.active = other
    scene.timeline_markers.new("chorus", frame=30)
    scene.frame_start, scene.frame_end, scene.frame_current = 10, 90, 42
    patches = {
        "song strip": (song_strips, "song_strip"), "new rig": (pipeline.rig, "create_rig"),
        "second take": (keyframes, "write_action"), "markers": (markers, "set_markers"),
        "panel settings": (properties.DanceNetSettings, "remember_analysis"),
    }  # fmt: skip
    owner, name = patches[step]
    original = getattr(owner, name)
    monkeypatch.setattr(owner, name, _fail_after(original, calls=2 if step == "second take" else 1))
    settings = {"takes": 2, "target": target} | ({"armature": rig} if rig is not None else {})
    props = scene.dancenet
    props.music_source, props.music_file = "FILE", str(song)
    for key, value in settings.items():
        setattr(props, key, value)
    before = snapshot(scene)
    rig_before = rig_state(rig) if rig is not None else None
    with pytest.raises(RuntimeError) as report:
        bpy.ops.dancenet.generate()
    message = str(report.value).strip()
    assert "Injected: injected failure" in message and message.endswith("nothing was changed")
    assert "Traceback" not in message
    assert snapshot(scene) == before
    if rig is not None:
        assert rig_state(rig) == rig_before
    assert [o.name for o in bpy.context.selected_objects] == ["Lamp post"]
    assert bpy.context.view_layer.objects.active == other
    monkeypatch.setattr(owner, name, original)
    assert generate(scene, song) == {"FINISHED"}  # and the next Generate works


_CRAFTED = ["{", "[]", '{"song": 1}', "[" * 100_000 + "]" * 100_000, "1" * 5000, '"text"']


@pytest.mark.parametrize("text", _CRAFTED, ids=["broken", "list", "wrong fields", "nested", "huge number", "string"])
def test_what_a_crafted_blend_stores_is_left_unread_never_raised(scene, addon, song, text):
    """Any saved file the add-on reads: a .blend whose take record, beat markers or last analysis were
    damaged or crafted draws its panels, answers polls and dances; the take just is not one, the analysis not
    shown, and markers it cannot read are left where they are."""
    assert generate(scene, song) == {"FINISHED"}
    rig = bpy.context.view_layer.objects.active
    action = rig.animation_data.action
    assert addon.takes.take_info(action) is not None
    action[addon.takes.TAKE_PROP] = text
    scene[addon.markers.MARKERS_PROP] = text
    scene.dancenet.analysis = text
    assert addon.takes.take_info(action) is None
    assert scene.dancenet.analysis_for(str(song)) is None
    assert not bpy.ops.dancenet.continue_dance.poll()
    shot = panel_screenshot()
    for panel in addon.panels.MAIN_PANELS:  # each with its sub-panels, through their real draw()
        assert "Generate Dance" in {w.text for w in shot.walk(shot.record_panel(bpy.context, panel))}
    assert generate(scene, song) == {"FINISHED"}  # markers it wrote before, now unreadable, are simply kept


def test_a_take_whose_dance_is_damaged_is_one_line(scene, addon, song):
    assert generate(scene, song) == {"FINISHED"}
    action = bpy.context.view_layer.objects.active.animation_data.action
    action[addon.takes.MOTION_PROP] = {"rotations": [0.0] * 7, "root": [0.0] * 3, "offsets": [0.0] * 165,
                                          "fps": 25.0}
    with pytest.raises(addon.pipeline.DanceNetError, match="holds no readable dance .*generate it again"):
        addon.takes.take_motion(action)
