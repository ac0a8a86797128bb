"""A skeleton's bones as our joints, for reading its motion (a library clip in any convention): the bone map
given, else Auto (`bonemap.auto_map`: by names, then by the skeleton's shape); a skeleton that is no humanoid is
answered in one line that says what it lacks."""

from __future__ import annotations

from collections.abc import Sequence

from ..errors import DanceNetError
from ..skeleton import JOINT_INDEX
from .bonemap import REQUIRED_JOINTS, SPINE_JOINTS, BoneMap, auto_map, match, name_key
from .shapemap import RestBone

_LIMBS = {"legs": ("hip", "knee", "ankle"), "arms": ("shoulder", "elbow", "wrist")}


def humanoid_joints(bones: Sequence[RestBone], name: str, bone_map: BoneMap | None = None) -> dict[int, str]:
    """Our joint index (`skeleton.JOINT_INDEX`) -> the bone of `bones` that plays it, by `bone_map` if given, else
    Auto. A one-line DanceNetError naming what is missing (no legs, two hips, the joints no bone was found for)
    when the skeleton cannot be read as one humanoid's."""
    return mapped_humanoid(bones, name, bone_map)[1]


def mapped_humanoid(bones: Sequence[RestBone], name: str,
                    bone_map: BoneMap | None = None) -> tuple[str, dict[int, str]]:
    """`humanoid_joints`, with the name of the bone map that read them (the convention found: "Mixamo",
    "VRM + shape", ...)."""
    names = [b.name for b in bones]
    chosen = bone_map if bone_map is not None else auto_map(bones, name)
    found, _ = match(chosen, names)
    twins: list[str] = []
    if bone_map is None:  # Auto: two bones alike for the hips are two bodies (a duet), which no one map reads
        wanted = chosen.bones.get("pelvis", [])
        keys = {name_key(w) for w in ([wanted] if isinstance(wanted, str) else wanted)}
        keys |= {name_key(found["pelvis"])} if "pelvis" in found else set()
        twins = [n for n in names if name_key(n) in keys]
    lacks = [f"two hips ({', '.join(twins[:3])})"] if len(twins) >= 2 else []
    lacks += _lacks(found | ({"pelvis": twins[0]} if lacks else {}))
    if lacks:
        shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
        raise DanceNetError(f"{name}: not a humanoid skeleton ({len(names)} bones: {shown}): {'; '.join(lacks)}")
    return chosen.name, {JOINT_INDEX[j]: b for j, b in found.items()}


def _lacks(found: dict[str, str]) -> list[str]:
    """What a skeleton with bones for `found` lacks to be read: a limb pair it has no bone of, a spine, the
    required joints it has none for."""
    missing = [j for j in REQUIRED_JOINTS if j not in found]
    told = []
    for limb, parts in _LIMBS.items():
        joints = [f"{side}_{part}" for side in ("left", "right") for part in parts]
        if all(j in missing for j in joints):
            told.append(f"no {limb}")
            missing = [j for j in missing if j not in joints]
    if missing:
        told.append("no bone for " + ", ".join(missing))
    if "pelvis" in found and "neck" in found and not any(j in found for j in SPINE_JOINTS):
        told.append("no spine between the hips and the neck")
    return told
