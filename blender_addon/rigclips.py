"""Motion-library clips from rigs: an FBX file of the Library folder, or an action of the open file that
animates a humanoid armature, sampled bone by bone as Blender evaluates it (constraints and drivers included) into
the core's `ArmatureClip`, which `dancenet_core.library.build` reads onto our skeleton whatever the rig's rest pose.

Each clip is sampled in a scene of its own that Blender shows nowhere: an FBX file is imported into it, an action
plays on a copy of its armature there. Everything made for it is removed after, so the user's objects, actions,
scenes and data blocks stay as they were, and so does the scene's frame. Main thread only (bpy).

An action of the file becomes a clip when its bone channels belong to an armature that Auto's bone map reads as a
humanoid (DanceNet's own takes are not clips: they are dances made from the library, not capture). Its style is the
action's custom property `dancenet_style` if set, else its name up to the first "_" ("salsa_basic" is salsa; a
name without "_" has no style). Its custom properties `dancenet_bpm` and `dancenet_meter`, where set, give its tempo
and beats per bar, which the library then takes instead of reading them from the motion (as a folder's
manifest.csv does).
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import bpy
import numpy as np

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError
from dancenet_core.rigmap import humanoid_map

from . import rigchoice, song, takes

if TYPE_CHECKING:  # the library's build code is loaded when a library is built, not with the add-on
    from dancenet_core.library.build import ArmatureClip
    from dancenet_core.library.fbx import RigSample

STYLE_PROP = "dancenet_style"
BPM_PROP, METER_PROP = "dancenet_bpm", "dancenet_meter"
_BONE_PATH = re.compile(r'^pose\.bones\["((?:[^"\\]|\\.)*)"\]')


def _ids() -> list[bpy.types.ID]:
    """Every data block of the file (objects, meshes, images, scenes, ...; not the window manager and screens)."""
    out = []
    for kind in dir(bpy.data):
        coll = getattr(bpy.data, kind, None)
        if isinstance(coll, bpy.types.bpy_prop_collection) and kind not in ("window_managers", "workspaces", "screens"):
            out += [i for i in coll if isinstance(i, bpy.types.ID)]
    return out


@contextmanager
def scratch_scene() -> Iterator[bpy.types.Scene]:
    """A scene of its own to import and play clips in, the window's while it lives (Blender's importers and its
    evaluation work on the window's scene); then the window's scene is the user's again, and the scene and every
    data block made while it lived are removed, whatever happens."""
    before = {i.as_pointer() for i in _ids()}
    window = bpy.context.window
    shown = window.scene if window is not None else None
    scene = bpy.data.scenes.new("DanceNet library clip")
    try:
        if window is not None:
            window.scene = scene
        with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
            yield scene
    finally:
        if window is not None:
            window.scene = shown
        bpy.data.batch_remove([i for i in _ids() if i.as_pointer() not in before])


def humanoid_joints(rig: bpy.types.Object) -> dict[int, str]:
    """Our joint index -> the rig's bone, by Auto's bone map (the user's saved maps and the VRM add-on's assignments
    count, as for a target rig); a one-line DanceNetError for an armature no bone map reads as a humanoid."""
    bones = rigchoice.rest_bones(rig)
    auto = rigmap.auto_map(bones, rig.name, rigchoice.saved_maps_dir(), humanoid_map(rig.data))
    return rigmap.humanoid_joints(bones, f"armature '{rig.name}'", auto)


def _frames(action: bpy.types.Action) -> range:
    first, last = action.frame_range
    return range(math.floor(first), math.ceil(last) + 1)


def sample_fbx(path: Path) -> RigSample:
    """An FBX file's armature animation (its bones as Blender evaluates them: `fbx.RigSample`), read as the
    command line's worker reads it (`fbx_worker`), in a scene of its own that is removed again, and cached by
    the file's content; a one-line DanceNetError when it holds none a library can use (also cached)."""
    from dancenet_core.library import fbx, fbx_worker

    where = fbx.sample_path(path)  # the file hashed once
    if (hit := fbx.load_sample(where)) is not None:
        if isinstance(hit, str):
            raise DanceNetError(hit)
        return hit
    with scratch_scene() as scene:
        try:
            fbx_worker.import_fbx(path)
            rig, frames = fbx_worker.animated_armature(scene)
            fbx_worker.only(rig, scene)
            sample = fbx_worker.sample_armature(rig, scene, frames, song.scene_fps(scene))
        except fbx_worker.ImporterOff:  # this Blender's fault, not the file's: not kept
            raise
        except DanceNetError as e:  # the file's own fault: the same next time
            fbx.save_sample(where, str(e))
            raise
    fbx.save_sample(where, sample)
    return sample


@dataclass(frozen=True)
class FileAction:
    """An action of the file (with its slot, where actions have slots) that animates a humanoid armature."""

    action: str
    slot: str | None
    armature: str
    style: str
    joints: tuple[tuple[int, str], ...]  # our joint -> the armature's bone, by Auto's bone map
    bpm: float | None = None  # the action's `dancenet_bpm` and `dancenet_meter`, where set
    meter: int | None = None

    @property
    def name(self) -> str:
        return self.action


def _channels(action: bpy.types.Action) -> list[tuple[bpy.types.ActionSlot | None, list[bpy.types.FCurve]]]:
    """(slot, its F-curves) of an action; one (None, F-curves) for an action without slots (Blender before 4.4)."""
    if not hasattr(action, "slots"):
        return [(None, list(action.fcurves))]
    out = []
    for slot in action.slots:
        curves = [fc for layer in action.layers for strip in layer.strips
                  if (bag := strip.channelbag(slot)) is not None for fc in bag.fcurves]
        out.append((slot, curves))
    return out


def _bones_of(curves: list[bpy.types.FCurve]) -> set[str]:
    names = set()
    for fc in curves:
        if m := _BONE_PATH.match(fc.data_path):
            names.add(m[1].replace('\\"', '"').replace("\\\\", "\\"))
    return names


def style_of(action: bpy.types.Action) -> str:
    """The clip's style: the action's `dancenet_style` property, else its name up to the first "_" (else none)."""
    own = action.get(STYLE_PROP)
    if isinstance(own, str) and own.strip():
        return own.strip()
    return action.name.split("_", 1)[0] if "_" in action.name else ""


def tempo_of(action: bpy.types.Action) -> tuple[float | None, int | None]:
    """The clip's tempo and beats per bar where the action's `dancenet_bpm` and `dancenet_meter` give them (else
    None: read from the motion); a one-line DanceNetError for a value that is neither."""
    from dancenet_core.library.build import MANIFEST_BPM, MANIFEST_METERS

    bpm, meter = action.get(BPM_PROP), action.get(METER_PROP)
    if bpm is not None and not (isinstance(bpm, int | float) and MANIFEST_BPM[0] <= bpm <= MANIFEST_BPM[1]):
        raise DanceNetError(f"its {BPM_PROP} {bpm!r} is not beats per minute ({MANIFEST_BPM[0]:g}-"
                            f"{MANIFEST_BPM[1]:g}); correct it or delete the property")
    if meter is not None and not (isinstance(meter, int | float) and meter in MANIFEST_METERS):
        raise DanceNetError(f"its {METER_PROP} {meter!r} is not beats per bar (2, 3, 4 or 6); correct it or delete "
                            "the property")
    return (None if bpm is None else float(bpm)), (None if meter is None else int(meter))


def file_actions() -> tuple[list[FileAction], list[str]]:
    """The file's actions that animate a humanoid armature, and one line per action that animates bones but cannot
    be a clip (its armature is gone, or is no humanoid)."""
    rigs = sorted((o for o in bpy.data.objects if o.type == "ARMATURE"), key=lambda o: o.name)
    humanoid: dict[str, dict[int, str] | str] = {}  # armature object -> its joints' bones, or why it is no humanoid
    found, notes = [], []
    for action in sorted(bpy.data.actions, key=lambda a: a.name):
        if action.get(takes.ACTION_PROP):
            continue
        for slot, curves in _channels(action):
            bones = _bones_of(curves)
            if not bones:
                continue  # an object's, a camera's, a shape key's animation: no dance
            rig = max(rigs, key=lambda o: len(bones.intersection(o.data.bones.keys())), default=None)
            if rig is None or 2 * len(bones.intersection(rig.data.bones.keys())) < len(bones):
                notes.append(f"{action.name}: no armature in this file has its bones")
                continue
            if rig.name not in humanoid:
                try:
                    humanoid[rig.name] = humanoid_joints(rig)
                except DanceNetError as e:
                    humanoid[rig.name] = str(e)
            joints = humanoid[rig.name]
            if isinstance(joints, str):
                notes.append(f"{action.name}: {joints}")
                continue
            try:
                bpm, meter = tempo_of(action)
            except DanceNetError as e:
                notes.append(f"{action.name}: {e}")
                continue
            found.append(FileAction(action.name, slot.identifier if slot is not None else None, rig.name,
                                    style_of(action), tuple(sorted(joints.items())), bpm, meter))
    return found, notes


def actions_key(actions: list[FileAction], fps: float) -> str:
    """A digest of what the file's actions would make a library of, read without playing them: each action's
    keys, its armature's rest pose, place and bone map (`FileAction.joints`), its style, and the scene's frame rate.
    (A change only to a rig's constraints or drivers is not seen: build again by hand.)"""
    h = hashlib.sha256(f"{fps!r}".encode())
    for item in actions:
        action, rig = bpy.data.actions[item.action], bpy.data.objects[item.armature]
        h.update(f"{item}\0".encode())
        for slot, curves in _channels(action):
            if slot is not None and slot.identifier != item.slot:
                continue
            for fc in curves:
                h.update(f"{fc.data_path}[{fc.array_index}]".encode())
                for field in ("co", "handle_left", "handle_right"):
                    values = np.empty(2 * len(fc.keyframe_points), dtype=np.float32)
                    fc.keyframe_points.foreach_get(field, values)
                    h.update(values.tobytes())
        h.update(np.array(rig.matrix_world, dtype=np.float64).tobytes())
        h.update(np.array([np.array(b.matrix_local) for b in rig.data.bones], dtype=np.float64).tobytes())
    return "actions-" + h.hexdigest()[:32]


def actions_signature(actions: list[FileAction], fps: float) -> tuple:
    """What changes with almost any edit of the actions, quick to read (no key's value): their names, armatures,
    bone maps and styles, and each channel's count of keys; what the panel, drawn often, tells a built library by
    (`actions_key` reads every key)."""
    counts = []
    for item in actions:
        action = bpy.data.actions[item.action]
        for slot, curves in _channels(action):
            if slot is None or slot.identifier == item.slot:
                counts.append(tuple(len(fc.keyframe_points) for fc in curves))
    return fps, tuple(actions), tuple(counts)


def sample_action(item: FileAction, fps: float) -> ArmatureClip:
    """The clip of a file action: played on a copy of its armature in a scene of its own (the armature, the action
    and the user's scene untouched), at the file's frame rate `fps`: its bones for our joints as Blender evaluates
    them (the core's sampling, `fbx_worker.sample_armature`: in metres)."""
    from dancenet_core.library.build import ArmatureClip
    from dancenet_core.library.fbx_worker import sample_armature

    action, rig = bpy.data.actions.get(item.action), bpy.data.objects.get(item.armature)
    if action is None or rig is None:
        raise DanceNetError(f"it or its armature '{item.armature}' is gone")
    with scratch_scene() as scene:
        copy = rig.copy()
        copy.parent = None
        copy.matrix_world = rig.matrix_world.copy()
        scene.collection.objects.link(copy)
        anim = copy.animation_data or copy.animation_data_create()
        for track in list(anim.nla_tracks):
            anim.nla_tracks.remove(track)
        anim.action = action
        if item.slot is not None:
            anim.action_slot = next(s for s in action.slots if s.identifier == item.slot)
        sample = sample_armature(copy, scene, _frames(action), fps)
        return ArmatureClip.from_sample(sample, dict(item.joints), item.action, item.style, item.bpm, item.meter)
