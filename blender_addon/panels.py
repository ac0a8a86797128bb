"""The DanceNet sidebar tab, in the 3D Viewport and in the Sequencer (same content)."""

from __future__ import annotations

import bpy

from dancenet_core.errors import DanceNetError
from dancenet_core.skeleton import JOINT_NAMES

from . import bonemap, operators, pipeline
from .menus import DANCENET_MT_presets
from .rigdef import REQUIRED_JOINTS


def _draw_analysis(layout: bpy.types.UILayout, analysis: dict) -> None:
    """The last analysis of this song: tempo and the style classifier's probabilities."""
    box = layout.box().column(align=True)
    box.label(text=f"Tempo {analysis['tempo_bpm']:.0f} BPM", icon="SOUND")
    for style, p in sorted(analysis["probabilities"].items(), key=lambda kv: -kv[1]):
        box.progress(factor=p, text=f"{style.replace('_', ' ').title()} {p:.0%}")


def _draw_matches(layout: bpy.types.UILayout, props: bpy.types.PropertyGroup) -> None:
    """What the bone map found on the target armature: each required joint's bone (saying which Auto found
    by the skeleton's shape rather than by name) or a warning, how many optional joints it drives, and the
    controls to give a joint another bone and to save the map."""
    box = layout.box().column(align=True)
    try:
        chosen = pipeline.current_map(props)
    except DanceNetError as e:
        box.label(text=str(e), icon="ERROR")
        return
    found, _ = bonemap.match(chosen, [b.name for b in props.armature.data.bones])
    missing = [j for j in REQUIRED_JOINTS if j not in found]
    box.prop(props, "show_matches", text=f"{chosen.name}: {len(found)} of {len(JOINT_NAMES)} joints matched",
             icon="TRIA_DOWN" if props.show_matches or missing else "TRIA_RIGHT", emboss=False)
    if props.show_matches or missing:  # always open while a joint the dance needs has no bone
        for joint in REQUIRED_JOINTS:
            if joint in found:
                how = " (by shape)" if joint in chosen.by_shape else ""
                box.label(text=f"{joint.replace('_', ' ')}: {found[joint]}{how}", icon="CHECKMARK")
            else:
                box.label(text=f"{joint.replace('_', ' ')}: no bone", icon="ERROR")
    row = box.row(align=True)
    row.prop(props, "fix_joint", text="")
    row.prop_search(props, "fix_bone", props.armature.data, "bones", text="")
    row.operator("dancenet.fix_bone", text="", icon="CHECKMARK")
    box.operator("dancenet.save_bone_map", icon="FILE_TICK")


class _DanceNetPanel:
    bl_region_type = "UI"
    bl_category = "DanceNet"
    bl_label = "DanceNet"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        props = context.scene.dancenet
        runtime = context.window_manager.dancenet
        row = layout.row(align=True)
        row.menu("DANCENET_MT_presets", text=DANCENET_MT_presets.bl_label, icon="PRESET")
        row.operator("dancenet.preset_add", text="", icon="ADD")
        row.operator("dancenet.preset_add", text="", icon="REMOVE").remove_active = True

        col = layout.column()
        col.row().prop(props, "music_source", expand=True)
        if props.music_source == "FILE":
            col.prop(props, "music_file", text="")
        else:
            strip = context.scene.sequence_editor.active_strip if context.scene.sequence_editor else None
            if strip is not None and strip.type == "SOUND":
                col.label(text=strip.name, icon="SOUND")
            else:
                col.label(text="Select a sound strip in the Sequencer", icon="INFO")

        col = layout.column()
        col.prop(props, "style")
        analysis = props.analysis_for(props.current_song(context.scene))
        if analysis:
            _draw_analysis(col, analysis)
        col.prop(props, "seed")
        col.prop(props, "temperature")
        col.prop(props, "takes")
        col.prop(props, "footfix")
        col.prop(props, "add_markers")
        col.prop(context.scene.render, "fps", text="Frame Rate")  # the dance is resampled to the scene's rate
        col.prop(props, "root_motion")
        col.prop(props, "use_part")
        if props.use_part:
            row = col.row(align=True)
            row.prop(props, "part_start", text="From")
            row.prop(props, "part_end", text="To")

        col = layout.column()
        col.row().prop(props, "target", expand=True)
        if props.target == "NEW":
            col.prop(props, "with_mesh")
        else:
            col.prop(props, "armature", text="")
            col.prop(props, "bone_map")
            if props.bone_map == "FILE":
                col.prop(props, "bone_map_file", text="")
            elif props.bone_map == "TEXT":
                col.prop(props, "bone_map_text", text="")
            col.operator("dancenet.edit_bone_map", icon="TEXT")
            if props.armature is not None and props.armature.type == "ARMATURE":
                _draw_matches(col, props)

        if runtime.running:
            row = layout.row(align=True)
            row.progress(factor=runtime.progress, text=f"{runtime.stage} {runtime.progress:.0%}")
            row.operator("dancenet.cancel", text="", icon="CANCEL")
        else:
            row = layout.row()
            row.scale_y = 1.5
            row.operator("dancenet.generate", icon="PLAY_SOUND")
            layout.operator("dancenet.continue_dance", icon="FF")

        rig_obj = operators.export_target(context)
        takes = pipeline.takes_of(rig_obj) if rig_obj is not None else []
        if takes:
            box = layout.box().column(align=True)
            box.label(text="Takes (NLA)", icon="NLA")
            active = rig_obj.animation_data.action
            for _track, action in reversed(takes):  # newest first, as in the NLA editor
                chosen = action == active
                op = box.operator("dancenet.choose_take", text=action.name, depress=chosen,
                                  icon="RADIOBUT_ON" if chosen else "RADIOBUT_OFF")
                op.action = action.name
        if rig_obj is not None and rig_obj.animation_data and rig_obj.animation_data.action:
            row = layout.row(align=True)
            row.operator("dancenet.export_fbx", icon="EXPORT")
            row.operator("dancenet.export_bvh", icon="EXPORT")


class DANCENET_PT_view3d(_DanceNetPanel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_idname = "DANCENET_PT_view3d"


class DANCENET_PT_sequencer(_DanceNetPanel, bpy.types.Panel):
    bl_space_type = "SEQUENCE_EDITOR"
    bl_idname = "DANCENET_PT_sequencer"


CLASSES = (DANCENET_PT_view3d, DANCENET_PT_sequencer)
