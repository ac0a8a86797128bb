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
    when the skeleton cannot be read as a humanoid's."""
    names = [b.name for b in bones]
    chosen = bone_map if bone_map is not None else auto_map(bones, name)
    found, _ = match(chosen, names)
    missing = [j for j in REQUIRED_JOINTS if j not in found]
    if not any(j in found for j in SPINE_JOINTS) and not ({"pelvis", "neck"} - found.keys()):
        missing.append("spine")
    if missing:
        raise DanceNetError(f"{name}: not a humanoid skeleton ({len(names)} bones: {', '.join(names[:4])}"
                            f"{', ...' if len(names) > 4 else ''}): {_lacks(chosen, names, missing)}; name its "
                            "bones in a bone map (docs/library.md)")
    return {JOINT_INDEX[j]: b for j, b in found.items()}


def _lacks(bone_map: BoneMap, names: list[str], missing: list[str]) -> str:
    """What `missing` says of the skeleton: a limb pair it has no bone of, a joint two bones claim alike (two
    skeletons in one file), else the joints themselves."""
    told: list[str] = []
    left = list(missing)
    for limb, parts in _LIMBS.items():
        joints = [f"{side}_{part}" for side in ("left", "right") for part in parts]
        if all(j in missing for j in joints):
            told.append(f"no {limb}")
            left = [j for j in left if j not in joints]
    for joint in list(left):
        if joint == "spine":
            told.append("no spine between the hips and the neck")
            left.remove(joint)
            continue
        wanted = bone_map.bones.get(joint)
        keys = {name_key(w) for w in ([wanted] if isinstance(wanted, str) else wanted or [])}
        alike = [n for n in names if name_key(n) in keys]
        if len(alike) >= 2:
            told.append(f"two {_plain(joint)}s ({', '.join(alike[:2])})")
            left.remove(joint)
    if left:
        told.append("no bone for " + ", ".join(left))
    return "; ".join(told)


def _plain(joint: str) -> str:
    """'pelvis' -> 'hip' (what a user calls it), 'left_knee' -> 'left knee'."""
    return "hip" if joint == "pelvis" else joint.replace("_", " ")
