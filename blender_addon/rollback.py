"""Put the file back as it was when applying a dance fails half-way, whatever the failure.

Applying a result changes the scene step by step (a sound strip, a rig, actions, NLA tracks, constraints,
markers, frame range, the panel's settings). What can be checked is checked first, but a failure can still
come at any step (a rig that changes while the dance is made, memory, a bug), and "a failed run leaves the
file as it was" must hold for every one: this records what those steps may touch and undoes it.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import bpy

# Data-block kinds a Generate may add (a new rig brings an armature, a mesh, a material; a song a sound).
_ID_KINDS = ("objects", "actions", "armatures", "meshes", "materials", "sounds", "collections", "texts")
_POSE_CHANNELS = ("rotation_mode", "location", "rotation_quaternion", "rotation_euler", "rotation_axis_angle", "scale")


def _plain(value: Any) -> Any:
    """A property value as a comparable copy (vectors and arrays as tuples)."""
    return tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value


def _strips(scene: bpy.types.Scene) -> Any:
    editor = scene.sequence_editor
    return editor.strips if hasattr(editor, "strips") else editor.sequences


class _RigState:
    """What applying a dance may change on an existing rig: its animation slot, NLA tracks, pose, constraints
    and custom properties of its pose bones (control switches)."""

    def __init__(self, rig: bpy.types.Object) -> None:
        self.rig = rig
        anim = rig.animation_data
        self.had_anim = anim is not None
        self.action = anim.action if anim is not None else None
        self.slot = getattr(anim, "action_slot", None) if anim is not None else None
        self.tracks = {t.as_pointer(): t.mute for t in anim.nla_tracks} if anim is not None else {}
        self.pose = {
            pb.name: (
                {c: _plain(getattr(pb, c)) for c in _POSE_CHANNELS},
                [(con.mute, con.influence) for con in pb.constraints],
                {k: v for k, v in pb.items() if isinstance(v, int | float | str)},
            )
            for pb in rig.pose.bones
        }

    def restore_animation(self) -> None:
        """The rig's action and NLA tracks as they were (before the actions made for it are removed)."""
        rig = self.rig
        if not self.had_anim:
            rig.animation_data_clear()
        elif rig.animation_data is not None:
            anim = rig.animation_data
            for track in list(anim.nla_tracks):
                if track.as_pointer() not in self.tracks:
                    anim.nla_tracks.remove(track)
                elif track.mute != self.tracks[track.as_pointer()]:
                    track.mute = self.tracks[track.as_pointer()]
            anim.action = self.action
            if self.slot is not None:
                anim.action_slot = self.slot

    def restore_pose(self) -> None:
        """Pose values, constraint states and custom properties as they were (after the frame is set: the
        pose an unkeyed rig had, not one evaluated from a take)."""
        rig = self.rig
        for pb in rig.pose.bones:
            if pb.name not in self.pose:
                continue
            channels, constraints, custom = self.pose[pb.name]
            for name, value in channels.items():
                if _plain(getattr(pb, name)) != value:
                    setattr(pb, name, value)
            for con, (mute, influence) in zip(pb.constraints, constraints, strict=False):
                con.mute, con.influence = mute, influence
            for key, value in custom.items():
                if pb.get(key) != value:
                    pb[key] = value


class SceneState:
    """A record of everything applying a dance may change, and `restore` to go back to it."""

    def __init__(self, context: bpy.types.Context, rig: bpy.types.Object | None) -> None:
        scene = self.scene = context.scene
        self.view_layer = context.view_layer
        self.ids = {kind: {i.as_pointer() for i in getattr(bpy.data, kind)} for kind in _ID_KINDS}
        self.fake_users = {a.as_pointer(): a.use_fake_user for a in bpy.data.actions}
        self.had_editor = scene.sequence_editor is not None
        self.strips = {s.as_pointer() for s in _strips(scene)} if self.had_editor else set()
        self.frames = (scene.frame_start, scene.frame_end, scene.frame_current)
        self.sync = scene.sync_mode
        self.markers = [(m.name, m.frame, m.select, m.camera) for m in scene.timeline_markers]
        self.custom = {k: v for k, v in scene.items() if isinstance(v, int | float | str)}
        props = getattr(scene, "dancenet", None)
        self.props = {p.identifier: getattr(props, p.identifier) for p in props.bl_rna.properties[1:]
                      if not p.is_readonly} if props is not None else {}
        self.active = self.view_layer.objects.active
        self.selected = {o.as_pointer() for o in self.view_layer.objects if o.select_get()}
        self.rig = _RigState(rig) if rig is not None else None

    def restore(self) -> None:
        """Remove what was added and set back what was changed (objects first: they use the other data)."""
        scene = self.scene
        if self.rig is not None:
            self.rig.restore_animation()
        if not self.had_editor:
            scene.sequence_editor_clear()
        elif scene.sequence_editor is not None:
            strips = _strips(scene)
            for strip in [s for s in strips if s.as_pointer() not in self.strips]:
                strips.remove(strip)
        added = [i for kind in _ID_KINDS for i in getattr(bpy.data, kind) if i.as_pointer() not in self.ids[kind]]
        if added:
            bpy.data.batch_remove(added)
        for action in bpy.data.actions:
            if self.fake_users.get(action.as_pointer(), action.use_fake_user) != action.use_fake_user:
                action.use_fake_user = self.fake_users[action.as_pointer()]
        if [(m.name, m.frame, m.select, m.camera) for m in scene.timeline_markers] != self.markers:
            scene.timeline_markers.clear()
            for name, frame, select, camera in self.markers:
                marker = scene.timeline_markers.new(name, frame=frame)
                marker.select, marker.camera = select, camera
        for key in [k for k, v in scene.items() if k not in self.custom and isinstance(v, int | float | str)]:
            del scene[key]
        for key, value in self.custom.items():
            scene[key] = value
        start, end, current = self.frames
        scene.frame_start, scene.frame_end, scene.frame_start = start, end, start  # either order may clamp
        scene.frame_set(current)
        scene.sync_mode = self.sync
        props = getattr(scene, "dancenet", None)
        for name, value in self.props.items():
            if getattr(props, name) != value:
                setattr(props, name, value)
        if self.rig is not None:
            self.rig.restore_pose()
        for obj in self.view_layer.objects:
            obj.select_set(obj.as_pointer() in self.selected)
        self.view_layer.objects.active = self.active


@contextmanager
def undone_on_failure(context: bpy.types.Context, rig: bpy.types.Object | None) -> Iterator[None]:
    """Run the block; if it raises, restore the scene (and `rig`) as they were before it, then re-raise."""
    state = SceneState(context, rig)
    try:
        yield
    except BaseException:
        state.restore()
        raise
