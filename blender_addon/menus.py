"""Where Blender users look first: Add > Armature > DanceNet Rig, File > Export > DanceNet dance, and
presets of the panel's settings (saved as Blender presets, so they are shared by every file)."""

from __future__ import annotations

import bpy
from bl_operators.presets import AddPresetBase

from dancenet_core.request import panel_options

PRESET_SUBDIR = "dancenet/settings"


class DANCENET_MT_presets(bpy.types.Menu):
    """The saved DanceNet settings; picking one sets the panel"""

    bl_label = "DanceNet Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"
    draw = bpy.types.Menu.draw_preset


class DANCENET_OT_preset_add(AddPresetBase, bpy.types.Operator):
    """Save the DanceNet settings under a name (or, with the minus button, remove the chosen preset)"""

    bl_idname = "dancenet.preset_add"
    bl_label = "Add DanceNet Preset"
    preset_menu = "DANCENET_MT_presets"
    preset_subdir = PRESET_SUBDIR
    preset_defines = ["props = bpy.context.scene.dancenet"]
    # How to dance, not what to dance to (the song, the armature and the frames belong to the file).
    preset_values = [f"props.{name}" for name in (
        "style", *(name for name, _default, _option in panel_options()), "add_markers", "target", "bone_map",
        "with_mesh",
    )]  # fmt: skip


def _add_armature(self: bpy.types.Menu, _context: bpy.types.Context) -> None:
    self.layout.operator("dancenet.add_rig", icon="OUTLINER_OB_ARMATURE")


def _export(self: bpy.types.Menu, _context: bpy.types.Context) -> None:
    self.layout.operator("dancenet.export_bvh", text="DanceNet Dance (.bvh)")
    self.layout.operator("dancenet.export_fbx", text="DanceNet Dancer (.fbx)")


CLASSES = (DANCENET_MT_presets, DANCENET_OT_preset_add)


def register() -> None:
    bpy.types.VIEW3D_MT_armature_add.append(_add_armature)
    bpy.types.TOPBAR_MT_file_export.append(_export)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_export.remove(_export)
    bpy.types.VIEW3D_MT_armature_add.remove(_add_armature)
