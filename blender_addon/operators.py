"""Operators: Generate Dance and Build Library (non-blocking), cancel, exports, bone-map editing, rig."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import bpy
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError

from . import export, job, library, pipeline, rig, rigchoice, takes

_REDRAW_AREAS = frozenset({"VIEW_3D", "SEQUENCE_EDITOR", "PREFERENCES"})


def _redraw(context: bpy.types.Context) -> None:
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type in _REDRAW_AREAS:
                area.tag_redraw()


class _Background:
    """Work on a worker thread, its progress in the status bar and the panel, Esc to cancel: subclasses say what to
    do (`plan`, on the main thread, then `_begin` starts the job) and what its result makes (`finish`, back on the
    main thread, a line for the report)."""

    doing = "The job"  # named in the line of an unexpected error

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return not context.window_manager.dancenet.running

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            planned = self.plan(context)
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self._begin(context, planned)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _start(self, context: bpy.types.Context, work: job.Job) -> None:
        """Start the worker and the timer that polls it."""
        self._job = work
        self._job.start()
        runtime = context.window_manager.dancenet
        runtime.running, runtime.cancel_requested = True, False
        self._timer = context.window_manager.event_timer_add(0.2, window=context.window)
        self._show(context, "Starting", 0.0)

    def _show(self, context: bpy.types.Context, stage: str, fraction: float) -> None:
        runtime = context.window_manager.dancenet
        runtime.stage, runtime.progress = stage, fraction
        context.workspace.status_text_set(f"DanceNet: {stage} {fraction:.0%}   (Esc to cancel)")
        _redraw(context)

    def _end(self, context: bpy.types.Context) -> None:
        context.window_manager.event_timer_remove(self._timer)
        context.window_manager.dancenet.running = False
        if context.workspace is not None:  # None while Blender loads another file and cancels us
            context.workspace.status_text_set(None)
        _redraw(context)

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if event.type == "ESC" or context.window_manager.dancenet.cancel_requested:
            self.cancel(context)
            self.report({"WARNING"}, "DanceNet: cancelled; nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        self._job.poll()
        if not self._job.done:
            self._show(context, *self._job.progress())
            return {"PASS_THROUGH"}
        self._end(context)
        if self._job.error is not None:
            self.report({"ERROR"}, job.error_message(self._job.error, self.doing))
            return {"CANCELLED"}
        try:
            line = self.finish(context, self._job.result)
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, line)
        return {"FINISHED"}

    def cancel(self, context: bpy.types.Context) -> None:
        """Esc, the Cancel button, or Blender ending the operator (file load): drop the job, touch nothing."""
        self._job.cancel()
        self._end(context)


class _Generate(_Background):
    """Generation; subclasses say what to generate (`plan`)."""

    bl_options = {"REGISTER", "UNDO"}
    doing = "Generation"

    def plan(self, context: bpy.types.Context) -> pipeline.Plan:
        """What to generate and where it goes, from the panel's settings."""
        return pipeline.prepare(context.scene)

    def execute(self, context: bpy.types.Context) -> set[str]:
        """The blocking path: scripts, batch mode, and any call without a window to stay responsive in."""
        try:
            plan = self.plan(context)
            applied = pipeline.generate_now(context, plan, pipeline.load_generator())
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, applied.summary())
        return {"FINISHED"}

    def _begin(self, context: bpy.types.Context, plan: pipeline.Plan) -> None:
        self._plan = plan
        self._start(context, job.generation(pipeline.load_generator, plan.request))

    def finish(self, context: bpy.types.Context, result: Any) -> str:
        return pipeline.apply_result(context, self._plan, result).summary()


class DANCENET_OT_generate(_Generate, bpy.types.Operator):
    """Generate a dance to the chosen song (runs in the background; Esc cancels and changes nothing)"""

    bl_idname = "dancenet.generate"
    bl_label = "Generate Dance"


class DANCENET_OT_continue(_Generate, bpy.types.Operator):
    """Keep the active take up to the current frame and dance the rest anew (new seed), flowing on from it"""

    bl_idname = "dancenet.continue_dance"
    bl_label = "Continue From Here"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        rig_obj = export_target(context)
        anim = rig_obj.animation_data if rig_obj is not None else None
        return super().poll(context) and anim is not None and takes.take_info(anim.action) is not None

    def plan(self, context: bpy.types.Context) -> pipeline.Plan:
        return pipeline.prepare_continue(context.scene, export_target(context))


class DANCENET_OT_redo_section(_Generate, bpy.types.Operator):
    """Keep the active take and dance one section of its song anew (new seed, the section's own settings), as a
    new take; the dance after the section flows on from it"""

    bl_idname = "dancenet.redo_section"
    bl_label = "Dance Section Anew"

    section: StringProperty(name="Section", description="The section of the song's form (A1, B1, A2, ...)")

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return DANCENET_OT_continue.poll(context)

    def plan(self, context: bpy.types.Context) -> pipeline.Plan:
        return pipeline.prepare_redo(context.scene, export_target(context), self.section)


class DANCENET_OT_build_library(_Background, bpy.types.Operator):
    """Read and analyse the library's clips: the Library folder's BVH and FBX files, or the armature actions in this
    file (in the background; Esc cancels), so that the library engine can dance from them"""

    bl_idname = "dancenet.build_library"
    bl_label = "Build Library"
    doing = "Library build"

    def plan(self, context: bpy.types.Context) -> job.Staged:
        """The build of the panel's library source: its rigs to sample in Blender, then the build."""
        return library.build_job(context.scene.dancenet)

    def execute(self, context: bpy.types.Context) -> set[str]:
        """The blocking path: scripts and any call without a window to stay responsive in."""
        try:
            line = library.build_now(context.scene.dancenet)
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        _redraw(context)  # the Style menu and the folder's state
        self.report({"INFO"}, line)
        return {"FINISHED"}

    def _begin(self, context: bpy.types.Context, build: job.Staged) -> None:
        self._start(context, build)

    def finish(self, context: bpy.types.Context, result: str) -> str:
        return result


class DANCENET_OT_choose_take(bpy.types.Operator):
    """Play this take: its NLA track and action become active, the other takes' tracks are muted"""

    bl_idname = "dancenet.choose_take"
    bl_label = "Choose Take"
    bl_options = {"REGISTER", "UNDO"}

    action: StringProperty(name="Take", description="The take's action")

    def execute(self, context: bpy.types.Context) -> set[str]:
        rig_obj = export_target(context)
        action = bpy.data.actions.get(self.action)
        if rig_obj is None or action is None or action not in [a for _t, a in takes.takes_of(rig_obj)]:
            self.report({"ERROR"}, f"'{self.action}' is not a take on the DanceNet target rig")
            return {"CANCELLED"}
        takes.choose_take(rig_obj, action)
        self.report({"INFO"}, f"Playing take '{action.name}'")
        return {"FINISHED"}


class DANCENET_OT_cancel(bpy.types.Operator):
    """Stop the running generation; the scene stays as it was"""

    bl_idname = "dancenet.cancel"
    bl_label = "Cancel"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.window_manager.dancenet.running

    def execute(self, context: bpy.types.Context) -> set[str]:
        context.window_manager.dancenet.cancel_requested = True
        return {"FINISHED"}


def export_target(context: bpy.types.Context) -> bpy.types.Object | None:
    """The active armature, else the panel's target armature."""
    obj = context.active_object
    if obj is not None and obj.type == "ARMATURE":
        return obj
    return context.scene.dancenet.armature


class _ExportDance(ExportHelper):
    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        rig_obj = export_target(context)
        return (
            rig_obj is not None
            and rig_obj.animation_data is not None
            and rig_obj.animation_data.action is not None
        )

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        action = export_target(context).animation_data.action
        self.filepath = bpy.path.clean_name(action.name) + self.filename_ext
        return super().invoke(context, event)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            path = self.write(context, export_target(context), Path(self.filepath))
        except (DanceNetError, RuntimeError) as e:
            self.report({"ERROR"}, str(e).strip().splitlines()[-1])
            return {"CANCELLED"}
        self.report({"INFO"}, f"Exported {path}")
        return {"FINISHED"}


class DANCENET_OT_export_bvh(_ExportDance, bpy.types.Operator):
    """Export the dance as BVH (Y up, metres)"""

    bl_idname = "dancenet.export_bvh"
    bl_label = "Export BVH"
    filename_ext = ".bvh"
    filter_glob: StringProperty(default="*.bvh", options={"HIDDEN"})

    def write(self, context: bpy.types.Context, rig_obj: bpy.types.Object, path: Path) -> Path:
        return export.export_bvh(context, rig_obj, path)


class DANCENET_OT_export_fbx(_ExportDance, bpy.types.Operator):
    """Export the dancer (rig, mesh, baked dance) as FBX for Unity, Unreal or another Blender"""

    bl_idname = "dancenet.export_fbx"
    bl_label = "Export FBX"
    filename_ext = ".fbx"
    filter_glob: StringProperty(default="*.fbx", options={"HIDDEN"})

    def write(self, context: bpy.types.Context, rig_obj: bpy.types.Object, path: Path) -> Path:
        return export.export_fbx(context, rig_obj, path)


class DANCENET_OT_edit_bone_map(bpy.types.Operator):
    """Copy the chosen bone map into a text block to edit, and use that text block"""

    bl_idname = "dancenet.edit_bone_map"
    bl_label = "Edit Bone Map"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        props = context.scene.dancenet
        if props.bone_map == "TEXT" and props.bone_map_text is not None:
            return {"FINISHED"}
        try:
            text = _map_to_text(props)
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Bone map copied to text '{text.name}': edit it in the Text Editor")
        return {"FINISHED"}


def _map_to_text(props: Any) -> bpy.types.Text:
    """The chosen map as it resolves on the target (each joint -> the bone it found, then the joints it did
    not find as written) in a new text block, which becomes the panel's map."""
    chosen = rigchoice.current_map(props)
    bones = dict(chosen.bones)
    if props.armature is not None:
        found, _ = rigmap.match(chosen, [b.name for b in props.armature.data.bones])
        bones = found | {j: b for j, b in chosen.bones.items() if j not in found}
    text = bpy.data.texts.new(f"{chosen.name} bone map.json")
    text.write(json.dumps({"name": f"{chosen.name} (edited)", "bones": bones}, indent=2) + "\n")
    props.bone_map_text, props.bone_map = text, "TEXT"
    return text


class DANCENET_OT_fix_bone(bpy.types.Operator):
    """Let the chosen bone play the chosen joint (the map becomes an editable text block first)"""

    bl_idname = "dancenet.fix_bone"
    bl_label = "Set Bone"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        props = context.scene.dancenet
        rig_obj = props.armature
        if rig_obj is None or props.fix_bone not in rig_obj.data.bones:
            self.report({"ERROR"}, f"Pick a bone of the target armature for {props.fix_joint}")
            return {"CANCELLED"}
        try:
            text = props.bone_map_text if props.bone_map == "TEXT" and props.bone_map_text else _map_to_text(props)
            edited = rigmap.parse(text.as_string(), f"text '{text.name}'")
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        edited.bones[props.fix_joint] = props.fix_bone
        text.from_string(json.dumps({"name": edited.name, "bones": edited.bones}, indent=2) + "\n")
        self.report({"INFO"}, f"{props.fix_joint} is now played by '{props.fix_bone}' (map in text '{text.name}')")
        return {"FINISHED"}


class DANCENET_OT_list_missing_joints(bpy.types.Operator):
    """List the optional joints (fingers, face, ...) that the target armature has no bone for, in the Info editor"""

    bl_idname = "dancenet.list_missing_joints"
    bl_label = "List Missing Joints"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        armature = context.scene.dancenet.armature
        return armature is not None and armature.type == "ARMATURE"

    def execute(self, context: bpy.types.Context) -> set[str]:
        props = context.scene.dancenet
        try:
            chosen = rigchoice.current_map(props)
            _, skipped = rigmap.resolve(chosen, [b.name for b in props.armature.data.bones], props.armature.name)
        except DanceNetError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        if not skipped:
            self.report({"INFO"}, f"Every joint of the dance has a bone on '{props.armature.name}'")
            return {"FINISHED"}
        for entry in skipped:  # one line each in the Info editor; the status bar keeps the summary below
            self.report({"INFO"}, f"Not on this rig: {entry}")
        self.report({"INFO"}, rigchoice.missing_summary(skipped))
        return {"FINISHED"}


class DANCENET_OT_save_bone_map(bpy.types.Operator):
    """Save the bone map as it fits this armature; Auto then uses it in every file for rigs it fits"""

    bl_idname = "dancenet.save_bone_map"
    bl_label = "Save Bone Map"

    name: StringProperty(name="Name", default="My rig", description="The map's name (and file name)")

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context: bpy.types.Context) -> set[str]:
        from dancenet_core.atomic import write_text

        props = context.scene.dancenet
        try:
            chosen = rigchoice.current_map(props)
            if props.armature is None:
                raise DanceNetError("Pick the target armature whose bone map to save")
            found, _ = rigchoice.resolve_map(props.armature, chosen)
            path = rigchoice.saved_map_path(self.name)
            path.parent.mkdir(parents=True, exist_ok=True)
            write_text(path, json.dumps({"name": self.name, "bones": found}, indent=2) + "\n")
        except (DanceNetError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Bone map '{self.name}' saved to {path}")
        return {"FINISHED"}


class DANCENET_OT_add_rig(bpy.types.Operator):
    """Add a DanceNet rig (55 bones, SMPL-X names) with a mannequin mesh, at the 3D cursor"""

    bl_idname = "dancenet.add_rig"
    bl_label = "DanceNet Rig"
    bl_options = {"REGISTER", "UNDO"}

    with_mesh: BoolProperty(name="Mannequin", default=True, description="Give the rig a simple body mesh")
    root_bone: BoolProperty(name="Root Bone", default=False,
                            description="A root bone on the floor above the hips, for Root Bone motion")

    def execute(self, context: bpy.types.Context) -> set[str]:
        rig_obj = rig.create_rig(context, pipeline.RIG_NAME, with_mesh=self.with_mesh, root_bone=self.root_bone)
        rig_obj.location = context.scene.cursor.location
        context.view_layer.objects.active = rig_obj
        return {"FINISHED"}


CLASSES = (
    DANCENET_OT_generate,
    DANCENET_OT_continue,
    DANCENET_OT_redo_section,
    DANCENET_OT_build_library,
    DANCENET_OT_choose_take,
    DANCENET_OT_cancel,
    DANCENET_OT_export_bvh,
    DANCENET_OT_export_fbx,
    DANCENET_OT_edit_bone_map,
    DANCENET_OT_fix_bone,
    DANCENET_OT_save_bone_map,
    DANCENET_OT_list_missing_joints,
    DANCENET_OT_add_rig,
)
