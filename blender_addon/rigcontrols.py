"""Control rigs (Rigify, Auto-Rig Pro): which control an animator turns for each joint, so a dance is keyed
on the controls rather than on the deform bones the mesh is skinned to. Pure data and names (no bpy).

A control rig's deform bones follow its controls through constraints. Keying the deform bones means muting
those constraints, and then the controls no longer move the mesh. Keying the FK controls (with the rig's
IK/FK switches on FK) keeps the rig whole: an animator refines the dance with the controls they know.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, replace

from dancenet_core.rigmap import REQUIRED_JOINTS

_SIDES = (("left", "L"), ("right", "R"))
_FINGERS = ("index", "middle", "ring", "pinky", "thumb")


@dataclass(frozen=True)
class ControlRig:
    """A rig family's controls: joint -> the controls that turn its bone, outermost first (the pelvis' first
    carries the body through space and is keyed with its location; Rigify's hips bone also hangs from an FK
    control below the torso), the control at the top of the rig (keyed with the floor path in Root Bone
    motion), the custom properties that switch limbs between IK and FK (property -> its value for FK).

    `exact` renames a deform bone to the bone that follows its controls exactly (Rigify's ORG- bones: the
    DEF- ones spread a limb's twist over segments), which the solve measures instead. `aimed` joints' bones
    are stretched between two controls that share their roll, so only where they point is solved for.
    """

    name: str
    controls: dict[str, tuple[str, ...]]
    floor: str
    switches: dict[str, float]
    exact: tuple[str, str] | None = None
    aimed: frozenset[str] = frozenset()


def _controls(axial: dict[str, tuple[str, ...]], limbs: tuple[tuple[str, str], ...], side: Callable[[str], str],
              finger: Callable[[str, int], str]) -> dict[str, tuple[str, ...]]:
    """A family's controls: its axial ones, then per side each limb joint's FK bone and each finger joint's."""
    controls = dict(axial)
    for name, s in _SIDES:
        for joint, bone in limbs:
            controls[f"{name}_{joint}"] = (f"{bone}.{side(s)}",)
        for f in _FINGERS:
            for n in (1, 2, 3):
                controls[f"{name}_{f}{n}"] = (f"{finger(f, n)}.{side(s)}",)
    return controls


# Below the torso's pivot Rigify's FK spine hangs downwards: spine_fk.001 turns the lower back, and
# spine_fk under it the hips bone.
_RIGIFY = _controls(
    {"pelvis": ("torso", "spine_fk"), "spine1": ("spine_fk.001",), "spine2": ("spine_fk.002",),
     "spine3": ("spine_fk.003",), "neck": ("neck",), "head": ("head",)},
    (("collar", "shoulder"), ("shoulder", "upper_arm_fk"), ("elbow", "forearm_fk"), ("wrist", "hand_fk"),
     ("hip", "thigh_fk"), ("knee", "shin_fk"), ("ankle", "foot_fk"), ("foot", "toe_fk")),
    lambda s: s, lambda f, n: f"{'' if f == 'thumb' else 'f_'}{f}.0{n}",
)  # fmt: skip
_AUTO_RIG_PRO = _controls(
    {"pelvis": ("c_root_master.x", "c_root.x"), "spine1": ("c_spine_01.x",), "spine2": ("c_spine_02.x",),
     "spine3": ("c_spine_03.x",), "neck": ("c_neck.x",), "head": ("c_head.x",)},
    (("collar", "c_shoulder"), ("shoulder", "c_arm_fk"), ("elbow", "c_forearm_fk"), ("wrist", "c_hand_fk"),
     ("hip", "c_thigh_fk"), ("knee", "c_leg_fk"), ("ankle", "c_foot_fk"), ("foot", "c_toes_fk")),
    str.lower, lambda f, n: f"c_{f}{n}",
)  # fmt: skip


# Rigify's limbs switch with IK_FK on their parent bone, Auto-Rig Pro's with ik_fk_switch on the IK
# controls; both read 1.0 as FK.
FAMILIES = (
    ControlRig("Rigify", _RIGIFY, "root", {"IK_FK": 1.0}, ("DEF-", "ORG-"),
               frozenset({"spine1", "spine2", *(f"{side}_{f}1" for side, _ in _SIDES for f in _FINGERS)})),
    ControlRig("Auto-Rig Pro", _AUTO_RIG_PRO, "c_traj", {"ik_fk_switch": 1.0}),
)


def find(bone_names: Collection[str], bone_map: Mapping[str, str]) -> ControlRig | None:
    """The family whose main control of every required joint the armature has, cut down to the joints the
    bone map drives and the controls the armature has; None for a plain skeleton (its bones are keyed)."""
    for family in FAMILIES:
        if all(family.controls[j][0] in bone_names for j in REQUIRED_JOINTS):
            present = {j: tuple(c for c in cs if c in bone_names) for j, cs in family.controls.items()}
            return replace(family, controls={j: cs for j, cs in present.items() if cs and j in bone_map})
    return None
