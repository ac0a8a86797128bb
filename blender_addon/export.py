"""BVH and FBX export of a dancing rig, with settings that re-import into Blender (and other tools) as is;
written to a temporary name and renamed into place, so an interrupted export never leaves half a file."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import bpy

from dancenet_core.atomic import atomic_path
from dancenet_core.errors import DanceNetError


def action_frames(rig: bpy.types.Object) -> tuple[int, int]:
    """The frame range of the rig's active action."""
    action = rig.animation_data.action if rig.animation_data else None
    if action is None:
        raise DanceNetError(f"'{rig.name}' has no action to export: generate a dance first")
    start, end = action.frame_range
    return round(start), round(end)


@contextmanager
def _selected(
    context: bpy.types.Context, objects: list[bpy.types.Object], active: bpy.types.Object
) -> Iterator[None]:
    """Select exactly `objects` with `active` active for an exporter, then restore the user's selection."""
    view_layer = context.view_layer
    before = [o for o in view_layer.objects if o.select_get()]
    before_active = view_layer.objects.active
    for o in before:
        o.select_set(False)
    for o in objects:
        o.select_set(True)
    view_layer.objects.active = active
    try:
        yield
    finally:
        for o in objects:
            o.select_set(False)
        for o in before:
            o.select_set(True)
        view_layer.objects.active = before_active


def _object_mode(context: bpy.types.Context) -> None:
    """Leave edit mode first, so edits to the armature are in the data the exporters read."""
    if context.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")


def _keyed_locations(action: bpy.types.Action) -> set[str]:
    """The bones whose location the action keys (layered actions since Blender 4.4, legacy before)."""
    if hasattr(action, "layers"):
        curves = [c for layer in action.layers for strip in layer.strips for bag in strip.channelbags
                  for c in bag.fcurves]
    else:
        curves = list(action.fcurves)
    return {c.data_path.split('"')[1] for c in curves
            if c.data_path.startswith("pose.bones[") and c.data_path.endswith(".location")}


def export_bvh(context: bpy.types.Context, rig: bpy.types.Object, path: str | Path) -> Path:
    """BVH of the rig's action. Blender writes armature space as is: our rigs store it Y-up, in metres.
    Location channels go on the root only, unless a child bone moves too (the hips under a root bone)."""
    path = Path(path)
    start, end = action_frames(rig)
    moving = _keyed_locations(rig.animation_data.action)
    root_only = all(rig.data.bones[b].parent is None for b in moving if b in rig.data.bones)
    _object_mode(context)
    with atomic_path(path) as tmp, _selected(context, [rig], rig), \
            context.temp_override(active_object=rig, object=rig):
        bpy.ops.export_anim.bvh(
            filepath=str(tmp), frame_start=start, frame_end=end, global_scale=1.0,
            rotate_mode="NATIVE", root_transform_only=root_only,
        )  # fmt: skip
    return path


def export_fbx(context: bpy.types.Context, rig: bpy.types.Object, path: str | Path) -> Path:
    """FBX of the rig, its meshes and the active action baked one key per frame.

    No leaf bones (they clutter other tools), no key simplification (the dance is already one key per
    frame), only the active action (not every take in the file), Blender's default -Z forward / Y up
    with the unit scale applied: Blender, Unity and Unreal read it back at the right size and facing.
    Blender's FBX importer starts the animation one frame later (its "Animation Offset" is 1).
    """
    path = Path(path)
    meshes = [o for o in rig.children if o.type == "MESH"]
    scene = context.scene
    scene_range = scene.frame_start, scene.frame_end
    frames = action_frames(rig)
    _object_mode(context)
    try:
        scene.frame_start, scene.frame_end = frames  # the exporter bakes the scene's frame range
        with atomic_path(path) as tmp, _selected(context, [rig, *meshes], rig):
            bpy.ops.export_scene.fbx(
                filepath=str(tmp), use_selection=True, object_types={"ARMATURE", "MESH"},
                add_leaf_bones=False, bake_anim=True, bake_anim_use_all_bones=True,
                bake_anim_use_nla_strips=False, bake_anim_use_all_actions=False,
                bake_anim_force_startend_keying=True, bake_anim_step=1.0, bake_anim_simplify_factor=0.0,
                apply_unit_scale=True, apply_scale_options="FBX_SCALE_NONE", global_scale=1.0,
                axis_forward="-Z", axis_up="Y", primary_bone_axis="Y", secondary_bone_axis="X",
                armature_nodetype="NULL", use_armature_deform_only=False, mesh_smooth_type="FACE",
            )  # fmt: skip
    finally:
        scene.frame_start, scene.frame_end = scene_range
    return path
