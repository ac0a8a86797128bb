"""Which bones of an armature play the dance's joints: the panel's bone-map choice (Auto, a shipped map, a file,
a text block), resolved against the rig, and the rig checks made before minutes of generation."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import bpy

from dancenet_core import rigmap
from dancenet_core.errors import DanceNetError
from dancenet_core.rigmap import RestBone, humanoid_map

# Which part of the body an optional joint belongs to, for the one-line summary of those a rig lacks.
_JOINT_GROUPS = (("fingers", ("index", "middle", "ring", "pinky", "thumb")), ("face", ("jaw", "eye")),
                 ("spine", ("spine",)), ("collars", ("collar",)), ("toes", ("foot",)))


def missing_summary(skipped: list[str]) -> str:
    """One line for the optional joints a rig lacks (`rigmap.resolve`'s "joint (bones)" entries), so the report
    fits the status bar: "30 optional joints not on this rig (fingers: 30)"; the list is one click away."""
    counts: dict[str, int] = {}
    for entry in skipped:
        joint = entry.split(" ", 1)[0]
        group = next((g for g, marks in _JOINT_GROUPS if any(m in joint for m in marks)), "other")
        counts[group] = counts.get(group, 0) + 1
    groups = ", ".join(f"{g}: {n}" for g, n in sorted(counts.items(), key=lambda gn: -gn[1]))  # most first
    plural = "s" if len(skipped) != 1 else ""
    return f"{len(skipped)} optional joint{plural} not on this rig ({groups})"


def resolve_map(
    rig_obj: bpy.types.Object, bone_map: rigmap.BoneMap | None
) -> tuple[dict[str, str], list[str]]:
    """(joint -> bone, skipped optional joints) for an armature; DanceNetError if the map does not fit."""
    chosen = bone_map or rigmap.auto_map(rest_bones(rig_obj), rig_obj.name, saved_maps_dir(),
                                         humanoid_map(rig_obj.data))
    return rigmap.resolve(chosen, [b.name for b in rig_obj.data.bones], rig_obj.name)


def check_rig(rig_obj: bpy.types.Object) -> None:
    """DanceNetError for a rig that cannot be posed into a dance: its world matrix (its own scale, or a parent's)
    flattens it or is not finite, so no bone's rotation can be solved for."""
    import numpy as np

    turn = np.array(rig_obj.matrix_world)[:3, :3]
    if not np.isfinite(turn).all() or np.linalg.svd(turn, compute_uv=False).min() < 1e-6:
        raise DanceNetError(f"Armature '{rig_obj.name}' has a zero scale ({', '.join(f'{v:g}' for v in rig_obj.scale)}"
                            ", or a parent's flattens it): give it a scale other than 0 (Object Properties > "
                            "Transform), then generate again")


def rest_bones(rig_obj: bpy.types.Object) -> list[RestBone]:
    """The armature's bones at rest in world space (Z up), for mapping by the skeleton's shape."""
    world = rig_obj.matrix_world
    return [RestBone(b.name, b.parent.name if b.parent else None, tuple(world @ b.head_local),
                     tuple(world @ b.tail_local)) for b in rig_obj.data.bones]


def saved_maps_dir() -> Path:
    """Where Save Bone Map puts a user's maps: Blender's user presets, shared by every file."""
    return Path(bpy.utils.user_resource("SCRIPTS", path="presets/dancenet/bonemaps"))


def saved_map_path(name: str) -> Path:
    """Where Save Bone Map puts the map called `name`: a file of that name, or a one-line error when the file is
    another map's (two names a file system cannot tell apart, "Rig 1" and "Rig_1"). The same name replaces its
    own map."""
    from dancenet_core.outputs import safe_name

    path = saved_maps_dir() / f"{safe_name(name, 'bone map')}.json"
    try:
        other = json.loads(path.read_text(encoding="utf-8")).get("name") if path.is_file() else name
    except (OSError, ValueError, AttributeError):
        other = None  # damaged or not a map: replaced
    if other not in (name, None):
        raise DanceNetError(f"'{other}' is saved as {path.name}; choose another name")
    return path


def current_map(props: Any) -> rigmap.BoneMap:
    """The bone map the panel's settings choose for the target armature (Auto: by names and shape, even when
    it does not fit, to start fixing from)."""
    chosen = chosen_map(props)
    if chosen is not None:
        return chosen
    rig_obj = props.armature
    if rig_obj is None or rig_obj.type != "ARMATURE":
        return rigmap.load_shipped("SMPLX")
    return rigmap.auto_map(rest_bones(rig_obj), rig_obj.name, saved_maps_dir(), humanoid_map(rig_obj.data))


def chosen_map(props: Any) -> rigmap.BoneMap | None:
    if props.bone_map == "AUTO":
        return None
    if props.bone_map == "FILE":
        return rigmap.load_file(bpy.path.abspath(props.bone_map_file))
    if props.bone_map == "TEXT":
        if props.bone_map_text is None:
            raise DanceNetError("Bone map 'Text' chosen but no text block picked")
        return rigmap.parse(props.bone_map_text.as_string(), f"text '{props.bone_map_text.name}'")
    return rigmap.load_shipped(props.bone_map)
