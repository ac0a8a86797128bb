"""Settings: per scene (saved with the .blend) and per session on the window manager (progress)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from dancenet_core.errors import first_line
from dancenet_core.request import ENERGY_SCALES, RETURN_CHOICES, Option, panel_options
from dancenet_core.skeleton import JOINT_NAMES

from . import library, operators, pipeline, preferences, takes
from .panelsettings import AS_DANCE

# Blender keeps only pointers to dynamic enum strings: the list must outlive the callback.
_style_items: list[tuple[str, str, str, int]] = []


_styles_problem: list[str] = []


def styles_problem() -> str | None:
    """Why the Style menu last came out without the styles (an import that failed), or None."""
    return _styles_problem[0] if _styles_problem else None


def _style_label(style: str) -> str:
    return style.replace("_", " ").replace("-", " ").title()


def _engine_styles(props: DanceNetSettings, context: bpy.types.Context | None) -> list[tuple[str, str, str, int]]:
    """Auto and the styles the chosen engine dances (the library's: its clips'), with the analysed song's
    probabilities in their labels. In Commercial Use only a library of the user's own is read for them: DanceNet's
    weights and the shipped library are parts it never opens (Generate Dance says why)."""
    analysis = props.analysis_for(props.current_song(context.scene)) if context is not None else None
    probs: dict[str, float] = analysis["probabilities"] if analysis else {}
    auto = "Auto"
    if analysis:
        auto = f"Auto ({_style_label(analysis['style'])})"
    commercial = preferences.commercial(props)
    items = [("auto", auto, "The style whose dance-sport tempo and meter fit the music's" if commercial
              else "Let the style classifier pick the style from the music", 0)]
    try:
        if props.engine == "library":  # the styles of the library's clips
            own = library.chosen_library(props, drawn=True)
            styles = [] if commercial and own is None else library.library_styles(own)
        else:
            styles = [] if commercial else pipeline.available_styles()
        _styles_problem[:] = []
    except ImportError as e:  # a broken install: said under the menu (styles_problem), not an empty menu
        styles = []
        _styles_problem[:] = [f"Styles cannot be listed: {first_line(e)}; reinstall the DanceNet extension"]
    for i, style in enumerate(styles, start=1):
        label = _style_label(style)
        if style in probs:
            label = f"{label}  {probs[style]:.0%}"
        items.append((style, label, f"Dance {_style_label(style)}", i))
    return items


def _with_own(items: list[tuple[str, str, str, int]], own: str) -> list[tuple[str, str, str, int]]:
    """The menu's items and, when the engine offers it no more, the style chosen before (said in its label:
    Generate then says the engine lacks it)."""
    if own and own not in {k for k, *_ in items}:
        items.append((own, f"{_style_label(own)} (not this engine's)", f"Dance {_style_label(own)}", len(items)))
    return items


def _by_name(items: list[tuple[str, str, str, int]], name: str) -> int:
    """The value of the menu's item `name` (the first item's where none): a dynamic enum is stored by its value,
    which points at another style once the engine, and so the list, changes; the name is kept instead."""
    return next((v for k, _l, _d, v in items if k == name), items[0][3])


def _styles(self: DanceNetSettings, context: bpy.types.Context | None) -> list[tuple[str, str, str, int]]:
    _style_items[:] = _with_own(_engine_styles(self, context), self.style_name)
    return _style_items


def _get_style(self: DanceNetSettings) -> int:
    return _by_name(_styles(self, bpy.context), self.style_name or "auto")


def _set_style(self: DanceNetSettings, value: int) -> None:
    self.style_name = next((k for k, _l, _d, v in _styles(self, bpy.context) if v == value), "auto")


_section_style_items: list[tuple[str, str, str, int]] = []


def _section_styles(self: Any, context: bpy.types.Context | None) -> list[tuple[str, str, str, int]]:
    """A section's style: the dance's, one of the styles the Style menu offers, or the section's own when the
    engine offers it no more."""
    props = context.scene.dancenet if context is not None else None
    styles = [item for item in (_engine_styles(props, context) if props is not None else []) if item[0] != "auto"]
    items = [(AS_DANCE, "As the Dance", "The dance's style", 0),
             *((k, label.split("  ")[0], d, i) for i, (k, label, d, _n) in enumerate(styles, 1))]
    _section_style_items[:] = _with_own(items, self.style_name)
    return _section_style_items


def _get_section_style(self: Any) -> int:
    return _by_name(_section_styles(self, bpy.context), self.style_name or AS_DANCE)


def _set_section_style(self: Any, value: int) -> None:
    self.style_name = next((k for k, _l, _d, v in _section_styles(self, bpy.context) if v == value), AS_DANCE)


class DanceNetSection(bpy.types.PropertyGroup):
    """Settings of one section of the song's form (A1, B1, A2, ...: its name is the item's name)."""

    style_name: StringProperty(options={"HIDDEN"})  # the section's style as chosen ("": the dance's)
    style: EnumProperty(name="Style", items=_section_styles, get=_get_section_style, set=_set_section_style,
                        description="Dance this section in another style (it is then danced anew)")
    energy: EnumProperty(name="Energy", default=AS_DANCE, items=[
        (AS_DANCE, "As the Dance", "The dance's energy"),
        *((e, e.replace("-", " ").title(), f"Dance this section {e} (it is then danced anew)") for e in ENERGY_SCALES)])
    returns: EnumProperty(name="Returns", default=AS_DANCE, items=[
        (AS_DANCE, "As the Dance", "As the Dance panel's Returns"), *RETURN_CHOICES],
        description="Where this section's music returns an earlier section's: repeat, mirror or dance anew")


def _is_armature(_self: Any, obj: bpy.types.Object) -> bool:
    return obj.type == "ARMATURE"


def _take_tracks() -> tuple[bpy.types.Object | None, list[bpy.types.NlaTrack]]:
    """The rig whose takes the panel lists (the active armature, else the target) and all its NLA tracks."""
    rig_obj = operators.export_target(bpy.context)
    if rig_obj is None or rig_obj.animation_data is None:
        return rig_obj, []
    return rig_obj, list(rig_obj.animation_data.nla_tracks)


def _get_take_index(_self: Any) -> int:
    """The Takes list's highlight: the NLA track of the rig's active take (-1: none). Read from the rig, not
    stored, so a take chosen anywhere else (a generation, the NLA editor) is the one shown."""
    rig_obj, tracks = _take_tracks()
    if not tracks:
        return -1
    active = rig_obj.animation_data.action
    return next((tracks.index(t) for t, action in takes.takes_of(rig_obj) if action == active), -1)


def _set_take_index(_self: Any, index: int) -> None:
    """A click on a take in the list plays it, as Choose Take does; a user's own track is never chosen."""
    rig_obj, tracks = _take_tracks()
    if 0 <= index < len(tracks):
        for track, action in takes.takes_of(rig_obj):
            if track == tracks[index]:
                takes.choose_take(rig_obj, action)


# The song may be given relative to the .blend ("//song.ogg", read through bpy.path.abspath); Blender 4.5+ warns
# unless the property says so, and 4.2-4.4 know no such option.
_BLEND_RELATIVE = (
    {"PATH_SUPPORTS_BLEND_RELATIVE"} if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties
    else set()
)


def _setting(default: Any, option: Option) -> Any:
    """The panel property of a request setting (`dancenet_core.request.panel_options`): its label, help, limits
    and choices come from the request, so a new setting needs no code here."""
    common = {"name": option.label, "default": default, "description": option.help[:1].upper() + option.help[1:]}
    if option.choices:
        return EnumProperty(items=list(option.choices), **common)
    if option.kind is Path:  # a folder; none is ""
        return StringProperty(subtype="DIR_PATH", options=_BLEND_RELATIVE, **(common | {"default": default or ""}))
    if option.kind is bool:
        return BoolProperty(**common)
    top = option.panel_max if option.panel_max is not None else option.maximum
    if option.kind is int:
        return IntProperty(min=int(option.minimum), max=min(int(top), 2**31 - 1), **common)
    return FloatProperty(min=option.minimum, max=top, soft_max=option.soft_max or top, **common)


class DanceNetSettings(bpy.types.PropertyGroup):
    music_source: EnumProperty(
        name="Music",
        items=[
            ("FILE", "File", "An audio file; it becomes a sound strip in the Sequencer"),
            ("STRIP", "Sound Strip", "The active sound strip in the Sequencer"),
        ],
        default="FILE",
    )
    music_file: StringProperty(name="Song", subtype="FILE_PATH", description="The song to dance to",
                               options={"ANIMATABLE"} | _BLEND_RELATIVE)
    style_name: StringProperty(options={"HIDDEN"})  # the dance's style as chosen ("": auto)
    style: EnumProperty(name="Style", items=_styles, get=_get_style, set=_set_style,
                        description="Dance style (Auto: chosen from the music)")
    use_part: BoolProperty(
        name="Part of the Song", default=False,
        description="Dance only between two timeline frames (a sound strip's trim is always honoured)",
    )
    part_start: IntProperty(name="From Frame", default=1, description="First timeline frame to dance")
    part_end: IntProperty(name="To Frame", default=250, description="Last timeline frame to dance")
    target: EnumProperty(
        name="Target",
        items=[
            ("NEW", "New Rig", "Build a DanceNet rig with a mannequin"),
            ("EXISTING", "Existing Armature", "Drive an armature you already have, through a bone map"),
        ],
        default="NEW",
    )
    armature: PointerProperty(name="Armature", type=bpy.types.Object, poll=_is_armature)
    bone_map: EnumProperty(
        name="Bone Map",
        items=[
            ("AUTO", "Auto", "Pick the shipped map that fits the armature's bone names"),
            ("SMPLX", "SMPL-X", "Bones named like the SMPL-X joints (DanceNet's own rig)"),
            ("MIXAMO", "Mixamo", "mixamorig:Hips, mixamorig:Spine, ..."),
            ("RIGIFY", "Rigify", "A generated Rigify rig, through its DEF- deform bones"),
            ("UNREAL", "Unreal Manny/Quinn", "pelvis, spine_01, thigh_l, ... (UE5 and the UE4 mannequin)"),
            ("VRM", "VRM / VRoid", "J_Bip_C_Hips, ... or the VRM humanoid names (hips, leftUpperLeg, ...)"),
            ("CC", "Character Creator", "CC_Base_Hip, CC_Base_L_Thigh, ... (Reallusion CC3/CC4)"),
            ("DAZ", "DAZ Genesis", "hip, lThighBend, lShldrBend, ... (Genesis 3/8)"),
            ("MPFB", "MakeHuman/MPFB", "root, spine05, upperleg01.L, ... (the default skeleton)"),
            ("GENERIC", "Generic Names", "thigh.L, Thigh_L, LeftThigh, L_Thigh, lThigh, ...: side marks, case and "
             "separators ignored"),
            ("FILE", "JSON File", "Your own map in a JSON file"),
            ("TEXT", "Text Block", "Your own map in a text block (see Edit Bone Map)"),
        ],
        default="AUTO",
    )
    bone_map_file: StringProperty(name="Map File", subtype="FILE_PATH")
    fix_joint: EnumProperty(name="Joint", items=[(j, j.replace("_", " "), "") for j in JOINT_NAMES],
                            description="The dance's joint to give another bone")
    fix_bone: StringProperty(name="Bone", description="The armature's bone that plays the joint")
    show_matches: BoolProperty(name="Show Matches", default=False,
                               description="List which bone plays each joint the dance needs")
    bone_map_text: PointerProperty(name="Map Text", type=bpy.types.Text)
    add_markers: BoolProperty(
        name="Beat Markers", default=True, description="Mark bars and beats on the timeline"
    )
    with_mesh: BoolProperty(name="Mannequin", default=True, description="Give a new rig a simple body mesh")
    take_index: IntProperty(name="Take", get=_get_take_index, set=_set_take_index, options=set(),
                            description="The take that plays: its NLA track is on, the other takes' are muted")
    analysis: StringProperty(options={"HIDDEN"})  # JSON of the last style analysis, kept with the file
    sections: CollectionProperty(type=DanceNetSection)  # per section of the last analysis' form, by name
    library_source: EnumProperty(
        name="Library Source",
        items=[
            ("FOLDER", "Folder", "The Library folder's BVH and FBX clips (subfolders or a manifest.csv name styles)"),
            ("ACTIONS", "Armature Actions in This File", "Every action of this file that animates a humanoid "
             "armature (style: the action's 'dancenet_style' property, else its name up to the first '_')"),
        ],
        default="FOLDER",
        description="Where the library engine's clips come from",
    )

    def current_song(self, scene: bpy.types.Scene) -> str:
        """The chosen song's absolute path, or "" when none is set (never raises: used while drawing)."""
        if self.music_source == "FILE":
            return bpy.path.abspath(self.music_file) if self.music_file else ""
        strip = scene.sequence_editor.active_strip if scene.sequence_editor else None
        sound = getattr(strip, "sound", None)
        return bpy.path.abspath(sound.filepath, library=sound.library) if sound else ""

    def remember_analysis(self, song: Path, result: Any) -> None:
        """Keep what the analysis heard (tempo, style, the form's sections) for the panel, and a settings item
        per section (those kept from before keep their settings)."""
        form = getattr(result, "form", None)
        sections = [] if form is None else [
            {"name": s.name, "start_s": float(s.start_s), "end_s": float(s.end_s)} for s in form.sections]
        self.analysis = json.dumps({
            "song": str(song), "style": result.style, "tempo_bpm": float(result.tempo_bpm),
            "probabilities": {k: float(v) for k, v in result.style_probabilities.items()}, "sections": sections,
        })  # fmt: skip
        names = [s["name"] for s in sections]
        for i in reversed(range(len(self.sections))):
            if self.sections[i].name not in names:
                self.sections.remove(i)
        for name in names:
            if name not in self.sections:
                self.sections.add().name = name

    def analysis_for(self, song: str) -> dict[str, Any] | None:
        """The last analysis, if it was of `song` (its sections a list, empty for an older file's)."""
        if not self.analysis or not song:
            return None
        data = takes.stored_json(self.analysis, dict)  # a damaged or crafted file: no analysis
        if not (data and isinstance(data.get("song"), str) and isinstance(data.get("style"), str)
                and isinstance(data.get("tempo_bpm"), int | float) and isinstance(data.get("probabilities"), dict)
                and all(isinstance(k, str) and isinstance(v, int | float) for k, v in data["probabilities"].items())):
            return None
        sections = data.get("sections", [])
        if not (isinstance(sections, list) and all(
                isinstance(s, dict) and isinstance(s.get("name"), str) and isinstance(s.get("start_s"), int | float)
                and isinstance(s.get("end_s"), int | float) for s in sections)):
            sections = []
        return data | {"sections": sections} if Path(data["song"]) == Path(song) else None


class DanceNetRuntime(bpy.types.PropertyGroup):
    """Session state of a running generation or install, drawn by the panel."""

    running: BoolProperty()
    stage: StringProperty()
    progress: FloatProperty(min=0.0, max=1.0, subtype="FACTOR")
    cancel_requested: BoolProperty()


DanceNetSettings.__annotations__.update({name: _setting(default, o) for name, default, o in panel_options()})
CLASSES = (DanceNetSection, DanceNetSettings, DanceNetRuntime)


@bpy.app.handlers.persistent
def _reset_runtime(_file: str) -> None:
    """The window manager is saved with the file: a file saved mid-generation must not load as busy."""
    for wm in bpy.data.window_managers:
        wm.dancenet.running = wm.dancenet.cancel_requested = False


def register() -> None:
    bpy.types.Scene.dancenet = PointerProperty(type=DanceNetSettings)
    bpy.types.WindowManager.dancenet = PointerProperty(type=DanceNetRuntime)
    bpy.app.handlers.load_post.append(_reset_runtime)


def unregister() -> None:
    bpy.app.handlers.load_post.remove(_reset_runtime)
    del bpy.types.WindowManager.dancenet
    del bpy.types.Scene.dancenet
