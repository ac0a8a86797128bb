"""The VRM add-on's humanoid bone assignments as a bone map: a rig the user (or the VRM importer) has assigned
there is mapped as assigned, whatever its bone names. Read with getattr only (no bpy), so a file without the
VRM add-on, or a rig it never saw, just has no such map.

The add-on keeps them on the armature data: VRM 1.0 in `vrm_addon_extension.vrm1.humanoid.human_bones`, one
property per human bone (`left_upper_leg.node.bone_name`), VRM 0.x in `...vrm0.humanoid.human_bones`, a
collection of items with `.bone` ("leftUpperLeg") and `.node.bone_name`.
"""

from __future__ import annotations

import re
from typing import Any

from .bonemap import BoneMap

_BODY = {"hips": "pelvis", "spine": "spine1", "chest": "spine2", "upper_chest": "spine3", "neck": "neck",
         "head": "head", "jaw": "jaw"}  # fmt: skip
_LIMBS = {"shoulder": "collar", "upper_arm": "shoulder", "lower_arm": "elbow", "hand": "wrist", "upper_leg": "hip",
          "lower_leg": "knee", "foot": "ankle", "toes": "foot", "eye": "eye_smplhf"}  # fmt: skip
_FINGERS = {"index": "index", "middle": "middle", "ring": "ring", "little": "pinky"}
_SEGMENTS = {"proximal": 1, "intermediate": 2, "distal": 3}
# VRM 1.0's thumb has a metacarpal, proximal and distal bone, VRM 0.x's a proximal, intermediate and distal one.
_THUMB = {"1.0": {"metacarpal": 1, "proximal": 2, "distal": 3}, "0.x": {"proximal": 1, "intermediate": 2, "distal": 3}}


def _joint(human_bone: str, version: str) -> str | None:
    """Our joint for a VRM human bone name (snake_case), or None for one we do not drive."""
    if human_bone in _BODY:
        return _BODY[human_bone]
    m = re.fullmatch(r"(left|right)_(.+)", human_bone)
    if m is None:
        return None
    side, part = m[1], m[2]
    if part in _LIMBS:
        return f"{side}_{_LIMBS[part]}"
    m = re.fullmatch(r"(thumb|index|middle|ring|little)_(\w+)", part)
    if m is None:
        return None
    segment = (_THUMB[version] if m[1] == "thumb" else _SEGMENTS).get(m[2])
    return None if segment is None else f"{side}_{_FINGERS.get(m[1], m[1])}{segment}"


def _bone_name(human_bone: Any) -> str:
    return str(getattr(getattr(human_bone, "node", None), "bone_name", "") or "")


def assigned(armature_data: Any) -> dict[str, str]:
    """Joint -> bone as the VRM add-on assigns them on `armature_data` (VRM 1.0 first, else 0.x); {} where the
    add-on is absent or nothing is assigned."""
    ext = getattr(armature_data, "vrm_addon_extension", None)
    found: dict[str, str] = {}
    v1 = getattr(getattr(getattr(ext, "vrm1", None), "humanoid", None), "human_bones", None)
    if v1 is not None:
        for human_bone in (*_BODY, *(f"{s}_{p}" for s in ("left", "right") for p in (
                *_LIMBS, *(f"{f}_{g}" for f in ("thumb", *_FINGERS) for g in ("metacarpal", *_SEGMENTS))))):
            joint, bone = _joint(human_bone, "1.0"), _bone_name(getattr(v1, human_bone, None))
            if joint is not None and bone:
                found[joint] = bone
    if found:
        return found
    for item in getattr(getattr(getattr(ext, "vrm0", None), "humanoid", None), "human_bones", None) or ():
        snake = re.sub(r"(?<!^)([A-Z])", r"_\1", str(getattr(item, "bone", "") or "")).lower()
        joint, bone = _joint(snake, "0.x"), _bone_name(item)
        if joint is not None and bone:
            found[joint] = bone
    return found


def humanoid_map(armature_data: Any) -> BoneMap | None:
    """The assignments as a bone map, or None where there are none."""
    bones = assigned(armature_data)
    return BoneMap("VRM humanoid (VRM add-on)", dict(bones)) if bones else None
