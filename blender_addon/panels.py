"""The DanceNet sidebar tab, in the 3D Viewport and in the Sequencer (same content): a main panel with the
Generate button and presets, and sub-panels (Music, Dance, Rig, Takes, Export) that fold like Blender's own."""

from __future__ import annotations

import bpy

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError
from dancenet_core.request import panel_options
from dancenet_core.rigmap import REQUIRED_JOINTS
from dancenet_core.skeleton import JOINT_NAMES

from . import library, operators, preferences, properties, rigchoice, takes
from .menus import DANCENET_MT_presets


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
        chosen = rigchoice.current_map(props)
    except DanceNetError as e:
        box.label(text=str(e), icon="ERROR")
        return
    found, unmatched = rigmap.match(chosen, [b.name for b in props.armature.data.bones])
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
    optional = [j for j in unmatched if j not in REQUIRED_JOINTS]  # as the dance's report counts them
    if optional:  # one line, whatever the count: the list itself goes to the Info editor on request
        row = box.row(align=True)
        row.label(text=rigchoice.missing_summary(optional), icon="INFO")
        row.operator("dancenet.list_missing_joints", text="", icon="TEXT")
    row = box.row(align=True)
    row.prop(props, "fix_joint", text="")
    row.prop_search(props, "fix_bone", props.armature.data, "bones", text="")
    row.operator("dancenet.fix_bone", text="", icon="CHECKMARK")
    box.operator("dancenet.save_bone_map", icon="FILE_TICK")


def _draw_library_build(layout: bpy.types.UILayout, props: bpy.types.PropertyGroup) -> None:
    """Build Library beside what the chosen source is (not built yet, built, missing); nothing while the folder is
    empty (the shipped library, built)."""
    if props.library_source == "ACTIONS":
        text, icon = library.actions_state(props)
    else:
        folder = library.chosen_folder(props)
        if folder is None:
            return
        text, icon = library.folder_state(folder)
    row = layout.row(align=True)
    row.operator("dancenet.build_library", icon="FILE_REFRESH")
    row.label(text=text, icon=icon)


def _draw_commercial(layout: bpy.types.UILayout, props: bpy.types.PropertyGroup) -> None:
    """What Commercial Use needs (`dancenet_core.request.check_commercial`): the Motion Library engine on clips of
    one's own; no library that may be used commercially ships with the add-on (docs/licence.md)."""
    if props.engine != "library":
        layout.label(text="Commercial Use dances with the Motion Library engine", icon="ERROR")
    elif props.library_source == "FOLDER" and library.chosen_folder(props) is None:
        layout.label(text="Commercial Use needs a library of your own clips", icon="ERROR")


def _draw_commercial_switch(layout: bpy.types.UILayout, props: bpy.types.PropertyGroup, label: str) -> None:
    """The scene's Commercial Use switch; where the add-on's preference sets it for every scene, the switch is
    shown on and greyed (the preference's own value), with a line saying where it is set."""
    if not preferences.commercial_only():
        layout.prop(props, "commercial")
        return
    row = layout.row()
    row.enabled = False
    row.prop(preferences.addon_preferences(), "commercial_only", text=label)
    layout.label(text="Set for every scene in Preferences > Add-ons > DanceNet", icon="LOCKED")


def _draw_frame_rate(layout: bpy.types.UILayout, render: bpy.types.RenderSettings) -> None:
    """The scene's frame rate as Blender keeps it, frames per `fps_base` seconds (30000 / 1001 = 29.97): the dance
    is resampled to that true rate."""
    col = layout.column(align=True)
    col.prop(render, "fps", text="Frame Rate")
    col.prop(render, "fps_base", text="Base")
    if render.fps_base != 1.0:
        col.label(text=f"{render.fps / render.fps_base:.4g} fps")


class DANCENET_UL_takes(bpy.types.UIList):
    """The rig's DanceNet takes, newest first as in the NLA editor; clicking one plays it (`take_index`)."""

    def draw_item(self, context: bpy.types.Context, layout: bpy.types.UILayout, data: bpy.types.AnimData,
                  item: bpy.types.NlaTrack, icon: int, active_data: bpy.types.PropertyGroup, active_propname: str,
                  index: int = 0, flt_flag: int = 0) -> None:  # fmt: skip
        playing = item.strips[0].action == data.action
        layout.label(text=item.strips[0].action.name, icon="PLAY" if playing else "ACTION")

    def filter_items(self, context: bpy.types.Context, data: bpy.types.AnimData,
                     propname: str) -> tuple[list[int], list[int]]:  # fmt: skip
        """Only the tracks holding a take (a user's own tracks stay in the NLA editor), filtered by name."""
        tracks = list(getattr(data, propname))
        ours = {track.as_pointer() for track, _ in takes.takes_of(data.id_data)}
        by_name = bpy.types.UI_UL_list.filter_items_by_name(self.filter_name, self.bitflag_filter_item, tracks)
        shown = by_name or [self.bitflag_filter_item] * len(tracks)
        flags = [flag if t.as_pointer() in ours else 0 for t, flag in zip(tracks, shown, strict=True)]
        return flags, list(range(len(tracks) - 1, -1, -1))  # newest (top track) first


class _DanceNetPanel:
    bl_region_type = "UI"
    bl_category = "DanceNet"
    bl_label = "DanceNet"

    def draw(self, context: bpy.types.Context) -> None:
        """Presets and the one button that matters; the settings are in the sub-panels below."""
        layout = self.layout
        runtime = context.window_manager.dancenet
        row = layout.row(align=True)
        row.menu("DANCENET_MT_presets", text=DANCENET_MT_presets.bl_label, icon="PRESET")
        row.operator("dancenet.preset_add", text="", icon="ADD")
        row.operator("dancenet.preset_add", text="", icon="REMOVE").remove_active = True
        if runtime.running:
            row = layout.row(align=True)
            row.progress(factor=runtime.progress, text=f"{runtime.stage} {runtime.progress:.0%}")
            row.operator("dancenet.cancel", text="", icon="CANCEL")
        else:
            row = layout.row()
            row.scale_y = 1.5
            row.operator("dancenet.generate", icon="PLAY_SOUND")
            layout.operator("dancenet.continue_dance", icon="FF")


class _SubPanel:
    """A fold of the DanceNet panel; `make_sub_panels` gives it a class per sidebar."""

    bl_region_type = "UI"
    bl_category = "DanceNet"


class _Music(_SubPanel):
    bl_label = "Music"

    def draw(self, context: bpy.types.Context) -> None:
        """The song (a file or a sound strip) and what the last analysis heard in it."""
        props = context.scene.dancenet
        col = self.layout.column()
        col.row().prop(props, "music_source", expand=True)
        if props.music_source == "FILE":
            col.prop(props, "music_file", text="")
        else:
            strip = context.scene.sequence_editor.active_strip if context.scene.sequence_editor else None
            if strip is not None and strip.type == "SOUND":
                col.label(text=strip.name, icon="SOUND")
            else:
                col.label(text="Select a sound strip in the Sequencer", icon="INFO")
        analysis = props.analysis_for(props.current_song(context.scene))
        if analysis:
            _draw_analysis(col, analysis)


class _Dance(_SubPanel):
    bl_label = "Dance"

    def draw(self, context: bpy.types.Context) -> None:
        """How the dance is made and keyed."""
        props = context.scene.dancenet
        col = self.layout.column()
        col.prop(props, "style")
        if properties.styles_problem():
            col.label(text=properties.styles_problem(), icon="ERROR")
        for name, _default, option in panel_options():  # the request's settings, in its order
            if name == "library" and props.engine != "library":  # a library folder means nothing to DanceNet
                continue
            if name == "library":
                col.prop(props, "library_source", text="Source")
                if props.library_source == "FOLDER":
                    col.prop(props, name)
                _draw_library_build(col, props)
                continue
            if name == "commercial":
                _draw_commercial_switch(col, props, option.label)
                continue
            col.prop(props, name)
        if preferences.commercial(props):
            _draw_commercial(col, props)
        col.prop(props, "add_markers")
        _draw_frame_rate(col, context.scene.render)
        col.prop(props, "use_part")
        if props.use_part:
            row = col.row(align=True)
            row.prop(props, "part_start", text="From")
            row.prop(props, "part_end", text="To")


class _Sections(_SubPanel):
    bl_label = "Sections"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Shown once a dance to the chosen song has read its form."""
        props = context.scene.dancenet
        analysis = props.analysis_for(props.current_song(context.scene))
        return bool(analysis and analysis["sections"])

    def draw(self, context: bpy.types.Context) -> None:
        """The song's sections (A1, B1, A2, ...: a letter that returns is music heard again), each with settings
        of its own for the next Generate, and a button that dances just that section of the active take anew."""
        props = context.scene.dancenet
        analysis = props.analysis_for(props.current_song(context.scene))
        redo = operators.DANCENET_OT_redo_section.poll(context)
        for section in analysis["sections"]:
            item = props.sections.get(section["name"])
            box = self.layout.box().column(align=True)
            row = box.row(align=True)
            row.label(text=f"{section['name']}   {section['start_s']:.1f}-{section['end_s']:.1f} s")
            sub = row.row(align=True)
            sub.enabled = redo
            sub.operator("dancenet.redo_section", text="", icon="FILE_REFRESH").section = section["name"]
            if item is not None:
                row = box.row(align=True)
                row.prop(item, "style", text="")
                row.prop(item, "energy", text="")
                row.prop(item, "returns", text="")


class _Rig(_SubPanel):
    bl_label = "Rig"

    def draw(self, context: bpy.types.Context) -> None:
        """Who dances: a new DanceNet rig, or the user's armature through a bone map."""
        props = context.scene.dancenet
        col = self.layout.column()
        col.row().prop(props, "target", expand=True)
        if props.target == "NEW":
            col.prop(props, "with_mesh")
            return
        col.prop(props, "armature", text="")
        col.prop(props, "bone_map")
        if props.bone_map == "FILE":
            col.prop(props, "bone_map_file", text="")
        elif props.bone_map == "TEXT":
            col.prop(props, "bone_map_text", text="")
        col.operator("dancenet.edit_bone_map", icon="TEXT")
        if props.armature is not None and props.armature.type == "ARMATURE":
            _draw_matches(col, props)


class _Takes(_SubPanel):
    bl_label = "Takes"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Shown once the rig has a take."""
        rig_obj = operators.export_target(context)
        return rig_obj is not None and bool(takes.takes_of(rig_obj))

    def draw(self, context: bpy.types.Context) -> None:
        """The takes on the rig's NLA tracks; the chosen one plays, the others are muted."""
        rig_obj = operators.export_target(context)
        self.layout.template_list("DANCENET_UL_takes", "", rig_obj.animation_data, "nla_tracks",
                                  context.scene.dancenet, "take_index", rows=3)  # fmt: skip


class _Figures(_SubPanel):
    bl_label = "Figures"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Shown when the active take was cut from a motion library."""
        return bool(_take_figures(context))

    def draw(self, context: bpy.types.Context) -> None:
        """What the active take is made of, to see and to credit: each figure's clip, where in the clip and where
        in the song (seconds)."""
        col = self.layout.column(align=True)
        for f in _take_figures(context):
            (c0, c1), (s0, s1) = f["clip_s"], f["song_s"]
            col.label(text=f"{s0:6.1f}-{s1:.1f} s   {f['clip']}  {c0:.1f}-{c1:.1f} s")


def _take_figures(context: bpy.types.Context) -> list[dict]:
    """The active take's figures as its record keeps them ([] for a DanceNet take or any other action)."""
    rig_obj = operators.export_target(context)
    anim = rig_obj.animation_data if rig_obj is not None else None
    info = takes.take_info(anim.action if anim is not None else None) or {}
    figures = info.get("figures")
    ok = isinstance(figures, list) and all(
        isinstance(f, dict) and isinstance(f.get("clip"), str) and all(
            isinstance(f.get(k), list) and len(f[k]) == 2 and all(isinstance(v, int | float) for v in f[k])
            for k in ("clip_s", "song_s")) for f in figures)
    return figures if ok else []


class _Export(_SubPanel):
    bl_label = "Export"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Shown once the rig has an action to export."""
        rig_obj = operators.export_target(context)
        return rig_obj is not None and rig_obj.animation_data is not None and rig_obj.animation_data.action is not None

    def draw(self, context: bpy.types.Context) -> None:
        """The active take out to other programs."""
        row = self.layout.row(align=True)
        row.operator("dancenet.export_fbx", icon="EXPORT")
        row.operator("dancenet.export_bvh", icon="EXPORT")


class DANCENET_PT_view3d(_DanceNetPanel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_idname = "DANCENET_PT_view3d"


class DANCENET_PT_sequencer(_DanceNetPanel, bpy.types.Panel):
    bl_space_type = "SEQUENCE_EDITOR"
    bl_idname = "DANCENET_PT_sequencer"


def make_sub_panels(parent: type[bpy.types.Panel]) -> tuple[type[bpy.types.Panel], ...]:
    """One class per fold for `parent`'s sidebar: Blender registers a panel for a single space type."""
    return tuple(
        type(f"{parent.bl_idname}_{fold.bl_label.lower()}", (fold, bpy.types.Panel), {
            "bl_space_type": parent.bl_space_type, "bl_parent_id": parent.bl_idname,
            "bl_idname": f"{parent.bl_idname}_{fold.bl_label.lower()}",
        })  # fmt: skip
        for fold in (_Music, _Dance, _Sections, _Rig, _Takes, _Figures, _Export)
    )


MAIN_PANELS = (DANCENET_PT_view3d, DANCENET_PT_sequencer)
SUB_PANELS = {parent.bl_idname: make_sub_panels(parent) for parent in MAIN_PANELS}
CLASSES = (*MAIN_PANELS, *(sub for subs in SUB_PANELS.values() for sub in subs), DANCENET_UL_takes)
