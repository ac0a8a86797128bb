"""Bone maps that bend and mappings the user already has (issue 27, items 2 and 3): rigs that lack a spine, neck
or toe bone of their convention, rigs assigned by the VRM add-on, rigs named by MMD Tools."""

from __future__ import annotations

import numpy as np
import pytest
from doubles import convention_rest, synthetic_motion
from scene_helpers import bpy, build_armature
from test_addon_animator import CONVENTIONS, landing_error

from dancenet_core.skeleton import DEFAULT_SKELETON


def without(rows, bone: str) -> list:
    """Rows with `bone` left out, its children hung on its parent (a rig of that family with one bone fewer)."""
    parent = next(p for b, p, _h, _t in rows if b == bone)
    return [(b, parent if p == bone else p, h, t) for b, p, h, t in rows if b != bone]


def dance_under_auto(scene, song, rig) -> dict[str, str]:
    """Generate Dance on `rig` with the bone map on Auto; returns the map it used."""
    scene.render.fps = 30
    props = scene.dancenet
    props.music_source, props.music_file, props.target, props.armature = "FILE", str(song), "EXISTING", rig
    assert bpy.ops.dancenet.generate() == {"FINISHED"}
    from blender_addon.pipeline import take_info

    return take_info(rig.animation_data.action)["bone_map"]


def test_a_character_creator_rig_without_a_waist_dances_under_auto(scene, addon, song):
    cc = addon.bonemap.load_shipped("CC")
    rows = without(convention_rest(cc.bones, scale=0.92, arm_scale=1.04, leg_scale=0.97, **CONVENTIONS["CC"]),
                   "CC_Base_Waist")
    rig = build_armature("CC without waist", rows, mixamo_import=False)
    mapping = dance_under_auto(scene, song, rig)
    assert (mapping["spine2"], mapping["spine3"]) == ("CC_Base_Spine01", "CC_Base_Spine02")  # each where it sits
    assert "spine1" not in mapping
    assert landing_error(rig, mapping, synthetic_motion(2.0, seed=0), scene.frame_start) < 0.05


# Per convention, bones its rigs sometimes lack: a spine bone (fewer spine bones), the lower of two neck bones
# (a neck twist bone above it), the toes; with the in-between bones the rig has. Each rig of the convention
# without it is still mapped by the convention's own map, and dances.
LACKING = [
    ("MIXAMO", "mixamorig:Spine1", {}), ("MIXAMO", "mixamorig:LeftToeBase", {}),
    ("RIGIFY", "DEF-spine.002", {}), ("RIGIFY", "DEF-spine.001", {}),
    ("UNREAL", "spine_05", {"spine3": "spine_04"}), ("UNREAL", "neck_01", {"neck": "neck_02"}),
    ("VRM", "J_Bip_C_UpperChest", {}), ("VRM", "J_Bip_L_ToeBase", {}),
    ("CC", "CC_Base_Waist", {}), ("CC", "CC_Base_Spine02", {}), ("CC", "CC_Base_NeckTwist01", {}),
    ("CC", "CC_Base_L_ToeBase", {}),
    ("DAZ", "abdomenLower", {}), ("DAZ", "chestUpper", {}), ("DAZ", "neckLower", {"neck": "neckUpper"}),
    ("MPFB", "spine05", {"spine1": "spine04"}), ("MPFB", "spine01", {"spine3": "spine02"}),
    ("MPFB", "neck01", {"neck": "neck02"}),
    ("GENERIC", "chest", {}), ("GENERIC", "toe_L", {}),
]  # fmt: skip


@pytest.mark.parametrize("convention,bone,splits", LACKING, ids=[f"{c}-{b}" for c, b, _s in LACKING])
def test_each_conventions_map_bends_to_a_rig_lacking_a_bone(scene, addon, song, convention, bone, splits):
    layout = CONVENTIONS[convention]
    shipped = addon.bonemap.load_shipped(convention)
    layout = layout | {"splits": layout.get("splits", {}) | splits}
    rows = convention_rest(shipped.bones, scale=0.92, arm_scale=1.04, leg_scale=0.97, **layout)
    rig = build_armature(f"{convention} without {bone}", without(rows, bone), mixamo_import=False)
    names = [b.name for b in rig.data.bones]
    assert addon.bonemap.detect(names, rig.name).name == shipped.name
    mapping = dance_under_auto(scene, song, rig)
    assert bone not in mapping.values()
    for joint, extra in splits.items():  # the alternative stands in for the missing bone
        assert mapping[joint] == extra
    assert landing_error(rig, mapping, synthetic_motion(2.0, seed=0), scene.frame_start) < 0.05


def test_a_missing_spine_bones_turn_is_spread_over_the_bones_present(scene, addon, song):
    """With the middle spine bone missing, the bone below it points where the dance puts the chest (it takes the
    missing bone's bend as well as its own), so the chest and all above it stay where the dance puts them."""
    from blender_addon import keyframes, rigdef

    smplx = addon.bonemap.load_shipped("SMPLX")
    rig = build_armature("short spine", without(convention_rest(smplx.bones), "spine2"), mixamo_import=False)
    mapping = {j: j for j in smplx.bones if j != "spine2"}
    motion = synthetic_motion(2.0, seed=3)
    keyframes.apply_motion(rig, motion, mapping, "short spine take", 1, 30.0)
    fk = motion.positions() @ rigdef.Y_UP_TO_Z_UP.T
    low, chest = (DEFAULT_SKELETON.index(j) for j in ("spine1", "spine3"))
    for f in range(0, motion.num_frames, 5):
        scene.frame_set(1 + f)
        theirs = np.subtract(*(rig.matrix_world @ rig.pose.bones[b].head for b in ("spine3", "spine1")))
        ours = fk[f, chest] - fk[f, low]
        cos = theirs @ ours / np.linalg.norm(theirs) / np.linalg.norm(ours)
        assert np.degrees(np.arccos(min(cos, 1.0))) < 0.5, f
