"""From the user's settings to a dancing rig: the request and where it goes (a Plan), then the result applied.

`prepare` reads the panel into a `dancenet_core.request.DanceRequest` (checked before any generation) and a
Placement; the worker thread (`job.py`) runs the generator on the request; `apply_result` (main thread) is the
only step that touches bpy data, so a cancelled or failed generation leaves the file exactly as it was, and a
failure while applying is undone (`rollback`). The song, the bone-map choice, the takes and the markers each
have their module (`song`, `rigchoice`, `takes`, `markers`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import bpy

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError
from dancenet_core.request import DanceRequest, SectionOverride

from . import library, markers, rig, rigchoice, rigcontrols, rollback, song, takes, warming
from .job import Generator, error_message
from .panelsettings import AS_DANCE, panel_settings

RIG_NAME = "DanceNet Dancer"


def load_generator() -> Generator:
    """The core's generate_dance (imported late: loading the generator costs a second)."""
    from dancenet_core.generate import generate_dance

    return generate_dance


_styles_cache: list[str] = []


def available_styles() -> list[str]:
    """The shipped model's styles, or [] while the model is missing (Generate Dance says why). An ImportError
    (a broken install) is raised: the Style menu shows its reason."""
    if not _styles_cache:
        try:
            from dancenet_core.generate import available_styles as core_styles

            _styles_cache.extend(core_styles())
        except (DanceNetError, OSError):
            return []
    return list(_styles_cache)


@dataclass
class Placement:
    """Where the result goes. Names, not bpy references: those can die while the generator runs."""

    armature: str | None = None  # None: build a new rig
    bone_map: rigmap.BoneMap | None = None  # None with an armature: detect
    strip: str | None = None  # the sound strip playing the song; None: add the song as a new strip
    song_frame: float = 1.0  # where a new strip for the song starts (an existing strip's own place wins)
    add_markers: bool = True
    with_mesh: bool = True
    frame_start: int | None = None  # a continued take starts where the take it continues did
    continues: str | None = None  # the action a continued take grows from
    redo_section: str | None = None  # the section a take danced anew (its name says so)


@dataclass
class Plan:
    request: DanceRequest
    placement: Placement = field(default_factory=Placement)


@dataclass
class Applied:
    """What apply_result made, for the report line and for callers (batch, tests)."""

    rig: str
    actions: list[str]
    frame_start: int
    frame_end: int
    style: str
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        made = f"{len(self.actions)} takes" if len(self.actions) > 1 else f"action '{self.actions[0]}'"
        text = f"Dance on '{self.rig}' ({self.style}), frames {self.frame_start}-{self.frame_end}, {made}"
        return "; ".join([text, *self.notes])


def prepare(scene: bpy.types.Scene) -> Plan:
    """Validate the scene's DanceNet settings into a Plan; raises DanceNetError for the user to read."""
    props = scene.dancenet
    if props.music_source == "STRIP":
        strip = scene.sequence_editor.active_strip if scene.sequence_editor else None
        if strip is None:
            raise DanceNetError(
                "No active sound strip: select the song's strip in the Sequencer, or choose a file"
            )
        path, strip_name = song.song_of_strip(strip), strip.name
    else:
        path, strip_name = song.check_song(props.music_file), None
        strip = song.strip_playing(scene, path)
    fps = song.scene_fps(scene)
    song_frame = song.song_zero_frame(strip, fps) if strip is not None else float(scene.frame_start)
    start_s, end_s = song.part_of_song(scene, strip, song_frame)
    placement = Placement(strip=strip_name, song_frame=song_frame, add_markers=props.add_markers,
                          with_mesh=props.with_mesh)
    # A style the installed model no longer has reads back as "": fall back to Auto.
    request = DanceRequest(path, **panel_settings(props), style=props.style or "auto", start_s=start_s,
                           end_s=end_s, fps=fps, sections=section_settings(props, str(path)))
    if request.engine == "library" and props.library_source == "ACTIONS":
        request = replace(request, library=_actions_library(props))
    request.check()
    if props.target == "EXISTING":
        target = props.armature
        if target is None or target.type != "ARMATURE":
            raise DanceNetError("No target armature: pick one in the DanceNet panel, or choose New Rig")
        placement.armature = target.name
        rigchoice.check_rig(target)
        from . import keyframes  # needs scipy (and the core's FK): loaded on first use

        placement.bone_map = rigchoice.chosen_map(props)
        hips = rigchoice.resolve_map(target, placement.bone_map)[0]["pelvis"]  # fail now, not after generating
        if request.root_motion == "root-bone" and keyframes.root_bone_of(target, hips) is None:
            raise DanceNetError(f"Root Bone motion needs a bone above the hips; '{hips}' of '{target.name}' has "
                                "none: choose New Rig (it gets a root bone) or another Root Motion")
    return Plan(request, placement)


def section_settings(props: Any, song_path: str) -> tuple[SectionOverride, ...]:
    """The Sections panel's settings that differ from the dance's, for the sections of the song's last analysis
    (none when the song was not analysed yet, or another song was)."""
    analysis = props.analysis_for(song_path)
    names = {s["name"] for s in analysis["sections"]} if analysis else set()
    out = []
    for item in props.sections:
        values = {key: getattr(item, key) for key in SectionOverride.KEYS}
        values = {k: v for k, v in values.items() if v and v != AS_DANCE}
        if item.name in names and values:
            out.append(SectionOverride(item.name, **values))
    return tuple(out)


def _actions_library(props: Any) -> Path:
    """The built library of the file's armature actions, or a one-line error saying to build it."""
    built = library.chosen_library(props)
    if built is None or not built.is_file():
        raise DanceNetError("The library of this file's armature actions is not built (or they changed since): "
                            "press Build Library first")
    return built


def _active_take(scene: bpy.types.Scene, rig_obj: bpy.types.Object | None,
                 what: str) -> tuple[bpy.types.Action, dict, Path, float]:
    """The rig's active take, its record, its song and the scene's frame rate, or a one-line error naming `what`
    needs it."""
    action = rig_obj.animation_data.action if rig_obj is not None and rig_obj.animation_data else None
    info = takes.take_info(action)
    if info is None:
        raise DanceNetError(f"{what} needs a rig whose active action is a DanceNet take: generate a dance first")
    return action, info, song.check_song(info["song"]), song.scene_fps(scene)


def prepare_continue(scene: bpy.types.Scene, rig_obj: bpy.types.Object | None) -> Plan:
    """A Plan that keeps the rig's active take up to the current frame and dances the rest with a new seed."""
    action, info, path, fps = _active_take(scene, rig_obj, "Continue From Here")
    first, last = (round(f) for f in action.frame_range)
    frame = scene.frame_current
    if not first + 2 <= frame <= last + 1 - fps:  # two kept frames give a velocity; a second left to dance
        raise DanceNetError(f"Put the current frame inside the take, from frame {first + 2} to {last + 1 - round(fps)} "
                            "(the dance is kept before it and danced anew from it)")
    continued = [a for a in bpy.data.actions if (takes.take_info(a) or {}).get("continues") == action.name]
    settings = panel_settings(info) | {"seed": info["seed"] + 1 + len(continued), "takes": 1}
    request = DanceRequest(path, **settings, style=info["style"], start_s=info["start_s"], end_s=info["end_s"],
                           fps=fps, continue_from=takes.take_motion(action), at_s=(frame - first) / fps)
    request.check()
    placement = Placement(armature=rig_obj.name, bone_map=rigmap.BoneMap(action.name, info["bone_map"]),
                          add_markers=False, frame_start=first, continues=action.name)
    return Plan(request, placement)


def prepare_redo(scene: bpy.types.Scene, rig_obj: bpy.types.Object | None, section: str) -> Plan:
    """A Plan that keeps the rig's active take and dances one section of its song anew (new seed; the section's
    own style and energy from the Sections panel), the take after it carried on: a new take beside the old."""
    action, info, path, fps = _active_take(scene, rig_obj, "Dance Section Anew")
    first = round(action.frame_range[0])
    analysis = scene.dancenet.analysis_for(str(path))
    found = next((s for s in (analysis or {}).get("sections", []) if s["name"] == section), None)
    if found is None:
        raise DanceNetError(f"The take's song has no section '{section}': generate a dance to it again so its "
                            "sections are read")
    own = next((o for o in section_settings(scene.dancenet, str(path)) if o.section == section), None)
    redone = [a for a in bpy.data.actions if (takes.take_info(a) or {}).get("continues") == action.name]
    settings = panel_settings(info) | {"seed": info["seed"] + 1 + len(redone), "takes": 1}
    motion = takes.take_motion(action)
    at_s = min(max(found["start_s"] - info["start_s"], 1.0 / fps), motion.duration)  # kept exactly before it
    request = DanceRequest(path, **settings, style=(own.style if own and own.style else info["style"]),
                           start_s=info["start_s"], end_s=info["end_s"], fps=fps, continue_from=motion, at_s=at_s,
                           redo_section=section)
    if own is not None and own.energy:
        request = replace(request, energy=own.energy)
    request.check()
    placement = Placement(armature=rig_obj.name, bone_map=rigmap.BoneMap(action.name, info["bone_map"]),
                          add_markers=False, frame_start=first, continues=action.name, redo_section=section)
    return Plan(request, placement)


def generate_now(context: bpy.types.Context, plan: Plan, generator: Generator) -> Applied:
    """Generate and apply on the calling thread: scripts, background mode, tests (never beside a warm-up step:
    `warming.generating`, as a worker's job)."""
    try:
        with warming.generating():
            result = generator(plan.request)
    except DanceNetError:
        raise
    except Exception as e:
        raise DanceNetError(error_message(e)) from e
    return apply_result(context, plan, result)


def _keep_users_action(target: bpy.types.Object) -> str | None:
    """Give the rig's current action a fake user if it is the user's own (not one of ours), so replacing it
    on the rig never loses it on save; returns a note for the report saying where it went."""
    anim = target.animation_data
    action = anim.action if anim is not None else None
    if action is None or action.get(takes.ACTION_PROP):
        return None
    action.use_fake_user = True
    return f"your action '{action.name}' was kept with a fake user (pick it again in the Action Editor)"


def apply_result(context: bpy.types.Context, plan: Plan, result: Any) -> Applied:
    """Put a generation result into the scene: song strip, frame range, markers, rig, one action per take.

    Any failure on the way (one line, DanceNetError) leaves the file as it was: what was added is removed and
    what was changed is set back (`rollback`), whichever step failed.
    """
    target = bpy.data.objects.get(plan.placement.armature) if plan.placement.armature is not None else None
    with rollback.undone_on_failure(context, target):
        try:
            return _apply_result(context, plan, result)
        except DanceNetError as e:
            raise DanceNetError(f"{e}; nothing was changed" if "nothing was changed" not in str(e) else str(e)) from e
        except Exception as e:
            raise DanceNetError(f"{error_message(e)}; nothing was changed") from e


def _key_takes(target: bpy.types.Object, result: Any, req: DanceRequest, place: Placement, bone_map: dict[str, str],
               frame_start: int) -> list[bpy.types.Action]:
    """Each take keyed onto `target` as an action of its own, named and recorded (its settings, song, bone map and
    figures) so it can be continued or danced again."""
    from dancenet_core.generate import shape_takes

    from . import keyframes  # needs scipy (the core's FK): loaded on first use

    actions = []
    for k, (motion, keyed) in enumerate(zip(result.motions, shape_takes(result.motions, req), strict=True), 1):
        name = takes.action_name(req.song, result.style, req.seed, k, len(result.motions))
        if place.redo_section is not None:
            name = f"{name} · {place.redo_section} anew"
        elif place.continues is not None:
            name = f"{name} · from frame {frame_start + round(req.at_s * req.fps)}"
        action = keyframes.apply_motion(target, keyed, bone_map, name, frame_start, None, req.root_motion)
        action[takes.ACTION_PROP] = True
        takes.store_take(action, motion, panel_settings(req) | {
            "song": str(req.song), "style": result.style, "start_s": result.start_s,
            "end_s": result.start_s + result.duration_s, "bone_map": bone_map, "continues": place.continues,
            "figures": (result.details[k - 1] if k <= len(result.details) else {}).get("danced_figures", []),
        })  # fmt: skip
        actions.append(action)
    return actions


def _apply_result(context: bpy.types.Context, plan: Plan, result: Any) -> Applied:
    """apply_result's steps, unguarded."""
    from . import keyframes  # needs scipy (the core's FK): loaded on first use

    scene = context.scene
    place = plan.placement
    target = None
    if place.armature is not None:
        target = bpy.data.objects.get(place.armature)
        if target is None or target.type != "ARMATURE":
            raise DanceNetError(f"The armature '{place.armature}' is gone; nothing was changed")
        rigchoice.check_rig(target)  # checked before the dance was made too, but the rig may have changed since
        bone_map, skipped = rigchoice.resolve_map(target, place.bone_map)
    strip = None
    if place.strip is not None:
        strip = song.strips_of(scene).get(place.strip) if scene.sequence_editor else None
        if strip is None:
            raise DanceNetError(f"The sound strip '{place.strip}' is gone; nothing was changed")

    fps = song.scene_fps(scene)
    req = replace(plan.request, fps=fps)  # keyed at the scene's rate now, whatever it was when asked
    if place.frame_start is not None:
        frame_start = place.frame_start
    else:
        if strip is None:
            strip = song.song_strip(scene, req.song, round(place.song_frame))
        # The dance starts where the part it was made for is heard (the strip's first audible frame by default).
        frame_start = round(song.song_zero_frame(strip, fps) + result.start_s * fps)
    notes: list[str] = []
    if target is None:
        target = rig.create_rig(context, RIG_NAME, result.motions[0].skeleton, place.with_mesh,
                                root_bone=req.root_motion == "root-bone")
        bone_map, skipped = {n: n for n in result.motions[0].skeleton.names}, []
        props = getattr(scene, "dancenet", None)
        if props is not None:  # the next Generate adds takes to this rig instead of building another
            props.target, props.armature, props.bone_map = "EXISTING", target, "AUTO"
            notes.append("the next Generate adds a take to this rig")
    elif (controls := rigcontrols.find(target.data.bones.keys(), bone_map)) is not None:
        notes.append(f"keyed {controls.name}'s FK controls (IK/FK switches on FK)")
    else:
        muted = keyframes.mute_overriding_constraints(target, list(bone_map.values()))
        if muted:
            notes.append(f"muted constraints on {len(muted)} bones so the keys show")
    if skipped:
        notes.append(rigchoice.missing_summary(skipped))

    kept = _keep_users_action(target)
    if kept:
        notes.append(kept)
    actions = _key_takes(target, result, req, place, bone_map, frame_start)
    frames = max(round(motion.duration * fps) for motion in result.motions)
    for action in actions:
        takes.add_take_track(target, action)
    takes.choose_take(target, actions[0])

    scene.frame_start, scene.frame_end = frame_start, frame_start + frames - 1
    scene.frame_set(frame_start)
    scene.sync_mode = "AUDIO_SYNC"  # playback keeps pace with the music
    if place.add_markers:
        markers.set_markers(scene, result, frame_start, fps)
    props = getattr(scene, "dancenet", None)
    if props is not None:
        props.remember_analysis(req.song, result)
    return Applied(
        target.name, [a.name for a in actions], scene.frame_start, scene.frame_end, result.style, notes
    )
