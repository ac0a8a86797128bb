"""Bone maps that bend and mappings the user already has: rigs that lack a spine, neck
or toe bone of their convention, rigs assigned by the VRM add-on, rigs named by MMD Tools."""

from __future__ import annotations

import json

import numpy as np
import pytest
from doubles import convention_rest, synthetic_motion
from scene_helpers import bpy, build_armature, fcurves_of
from test_addon_animator import CONVENTIONS, landing_error

from dancenet_core import rigmap
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
    from blender_addon.takes import take_info

    return take_info(rig.animation_data.action)["bone_map"]


def test_a_character_creator_rig_without_a_waist_dances_under_auto(scene, addon, song):
    cc = rigmap.load_shipped("CC")
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
    shipped = rigmap.load_shipped(convention)
    layout = layout | {"splits": layout.get("splits", {}) | splits}
    rows = convention_rest(shipped.bones, scale=0.92, arm_scale=1.04, leg_scale=0.97, **layout)
    rig = build_armature(f"{convention} without {bone}", without(rows, bone), mixamo_import=False)
    names = [b.name for b in rig.data.bones]
    assert rigmap.detect(names, rig.name).name == shipped.name
    mapping = dance_under_auto(scene, song, rig)
    assert bone not in mapping.values()
    for joint, extra in splits.items():  # the alternative stands in for the missing bone
        assert mapping[joint] == extra
    assert landing_error(rig, mapping, synthetic_motion(2.0, seed=0), scene.frame_start) < 0.05


def test_a_missing_spine_bones_turn_is_spread_over_the_bones_present(scene, addon, song):
    """With the middle spine bone missing, the bone below it points where the dance puts the chest (it takes the
    missing bone's bend as well as its own), so the chest and all above it stay where the dance puts them."""
    from blender_addon import keyframes, rigdef

    smplx = rigmap.load_shipped("SMPLX")
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


def vrm_addon_stand_in():
    """Property groups laid out as the VRM add-on's (saturday06/VRM-Addon-for-Blender) on Armature data:
    vrm_addon_extension.vrm1.humanoid.human_bones.<bone>.node.bone_name (VRM 1.0) and
    vrm_addon_extension.vrm0.humanoid.human_bones[i].bone / .node.bone_name (VRM 0.x); returns the classes."""
    from dancenet_core.rigmap.vrmhumanoid import _BODY, _FINGERS, _LIMBS, _SEGMENTS

    props = bpy.props

    def group(name: str, **fields):
        return type(f"StandInVrm{name}", (bpy.types.PropertyGroup,), {"__annotations__": fields})

    node = group("Node", bone_name=props.StringProperty())
    bone = group("1Bone", node=props.PointerProperty(type=node))
    names = [*_BODY, *(f"{s}_{p}" for s in ("left", "right") for p in (
        *_LIMBS, *(f"{f}_{g}" for f in ("thumb", *_FINGERS) for g in ("metacarpal", *_SEGMENTS))))]
    bones1 = group("1Bones", **{n: props.PointerProperty(type=bone) for n in names})
    humanoid1 = group("1Humanoid", human_bones=props.PointerProperty(type=bones1))
    vrm1 = group("1", humanoid=props.PointerProperty(type=humanoid1))
    bone0 = group("0Bone", bone=props.StringProperty(), node=props.PointerProperty(type=node))
    humanoid0 = group("0Humanoid", human_bones=props.CollectionProperty(type=bone0))
    vrm0 = group("0", humanoid=props.PointerProperty(type=humanoid0))
    ext = group("Extension", vrm0=props.PointerProperty(type=vrm0), vrm1=props.PointerProperty(type=vrm1))
    return [node, bone, bones1, humanoid1, vrm1, bone0, humanoid0, vrm0, ext]


@pytest.fixture
def vrm_addon():
    classes = vrm_addon_stand_in()
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Armature.vrm_addon_extension = bpy.props.PointerProperty(type=classes[-1])
    yield
    del bpy.types.Armature.vrm_addon_extension
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)


# Our joint -> the human bone the VRM add-on assigns it as, in VRM 1.0 and 0.x.
VRM_BONES = {"pelvis": ("hips", "hips"), "spine1": ("spine", "spine"), "spine2": ("chest", "chest"),
             "neck": ("neck", "neck"), "head": ("head", "head")}  # fmt: skip
for _s in ("left", "right"):
    for _joint, _v1, _v0 in (("collar", "shoulder", "Shoulder"), ("shoulder", "upper_arm", "UpperArm"),
                             ("elbow", "lower_arm", "LowerArm"), ("wrist", "hand", "Hand"),
                             ("hip", "upper_leg", "UpperLeg"), ("knee", "lower_leg", "LowerLeg"),
                             ("ankle", "foot", "Foot"), ("foot", "toes", "Toes")):
        VRM_BONES[f"{_s}_{_joint}"] = (f"{_s}_{_v1}", f"{_s}{_v0}")


@pytest.mark.parametrize("version", ["1.0", "0.x"])
def test_a_rig_assigned_by_the_vrm_addon_dances_as_assigned(scene, addon, song, vrm_addon, version):
    """Bones named so no shipped map fits (Bone.017 ...), assigned in the VRM add-on: Auto maps them as assigned."""
    smplx = rigmap.load_shipped("SMPLX")
    names = {j: f"Bone.{i:03d}" for i, j in enumerate(smplx.bones)}
    rows = convention_rest(smplx.bones, scale=0.92, a_pose_deg=30.0, arm_scale=1.04, leg_scale=0.97, names=names)
    rig = build_armature(f"VRM {version} rig", rows, mixamo_import=False)
    humanoid = getattr(rig.data.vrm_addon_extension, "vrm1" if version == "1.0" else "vrm0").humanoid
    for joint, (v1, v0) in VRM_BONES.items():
        if version == "1.0":
            getattr(humanoid.human_bones, v1).node.bone_name = names[joint]
        else:
            item = humanoid.human_bones.add()
            item.bone, item.node.bone_name = v0, names[joint]
    mapping = dance_under_auto(scene, song, rig)
    assert mapping == {j: names[j] for j in VRM_BONES}
    error = landing_error(rig, mapping, synthetic_motion(2.0, seed=0), scene.frame_start)
    print(f"VRM {version}: worst landing error {error:.4f} of the height")
    assert error < 0.023  # docs/animators.md: within 2.2%


def mmd_rows(english: bool) -> tuple[list, dict[str, str]]:
    """An MMD model's skeleton as MMD Tools imports it: two spine bones; 上半身 and 下半身 both start at the
    waist and hang from グルーブ < センター < 全ての親 (センター below the hips); 下半身 points down to the
    hips; the right side named as MMD Tools renames sides (ひじ.R), full-width digits; the legs' IK bones
    under 全ての親. `english`: MMD Tools' English names (LeftArm, Arm_R, LeftLegIK). Returns rows, joint -> bone."""
    mmd = bpy_free_map("MMD")
    names = {}
    for joint, (ja, en) in mmd.items():
        name = en if english else ja
        if joint.startswith("right_"):
            name = name.removeprefix("Right") + "_R" if english else name.removeprefix("右") + ".R"
        names[joint] = name if english else name.translate(str.maketrans("0123", "０１２３"))
    rows = without(convention_rest({j: [n] for j, n in names.items()}, scale=0.92, a_pose_deg=35.0, arm_scale=1.04,
                                   leg_scale=0.97, names=names), names.pop("spine3"))  # two spine bones
    at = {b: (h, t) for b, _p, h, t in rows}
    lower, upper, waist = names["pelvis"], names["spine1"], at[names["pelvis"]][0]
    hips = (at[names["left_hip"]][0] + at[names["right_hip"]][0]) / 2
    top, center, groove = ("ParentNode", "Center", "Groove") if english else ("全ての親", "センター", "グルーブ")
    rows = [(b, groove, waist, t) if b == upper else (b, p, h, t) for b, p, h, t in rows if b != lower]
    rows += [(top, None, np.zeros(3), np.array([0.0, 0.0, 0.1])),
             (center, top, hips - [0, 0, 0.15], hips - [0, 0, 0.2]), (groove, center, hips - [0, 0, 0.13], hips),
             (lower, groove, waist, hips)]
    for side, s in (("left", "Left" if english else "左"), ("right", "Right" if english else "右")):
        ankle, tip = at[names[f"{side}_ankle"]][0], at[names[f"{side}_foot"]][1]
        leg_ik = f"{s}LegIK" if english else f"{s}足ＩＫ"
        toe_ik = f"{s}ToeTipIK" if english else f"{s}つま先ＩＫ"
        rows += [(leg_ik, top, ankle, ankle + [0, 0.1, 0]), (toe_ik, leg_ik, tip, tip - [0, 0, 0.05])]
    return rows, names


def bpy_free_map(key: str) -> dict[str, list[str]]:

    return rigmap.load_shipped(key).bones


@pytest.mark.parametrize("english", [False, True], ids=["japanese", "english"])
def test_an_mmd_rig_dances_under_auto_with_its_leg_ik_muted(scene, addon, song, english):
    rows, names = mmd_rows(english)
    rig = build_armature("MMD model", rows, mixamo_import=False)
    for side, s in (("left", "Left" if english else "左"), ("right", "Right" if english else "右")):
        for bone, target, chain in ((names[f"{side}_knee"], f"{s}LegIK" if english else f"{s}足ＩＫ", 2),
                                    (names[f"{side}_ankle"], f"{s}ToeTipIK" if english else f"{s}つま先ＩＫ", 1)):
            ik = rig.pose.bones[bone].constraints.new("IK")
            ik.target, ik.subtarget, ik.chain_count = rig, target, chain
    mapping = dance_under_auto(scene, song, rig)
    assert mapping == {j: n for j, n in names.items() if j in mapping} and len(mapping) >= 45
    assert mapping["pelvis"] == ("LowerBody" if english else "下半身")
    center = "Groove" if english else "グルーブ"  # the bone above both halves of the body carries the travel
    paths = {fc.data_path for fc in fcurves_of(rig.animation_data.action)}
    assert f'pose.bones["{center}"].location' in paths
    assert f'pose.bones["{mapping["pelvis"]}"].location' not in paths
    iks = [c for b in rig.pose.bones for c in b.constraints if c.type == "IK"]
    assert len(iks) == 4 and all(c.mute for c in iks)  # off so the keys show; unmuting them hands the legs back
    motion = synthetic_motion(2.0, seed=0)
    error = landing_error(rig, {j: b for j, b in mapping.items() if j != "head"}, motion, scene.frame_start)
    head = landing_error(rig, {j: mapping[j] for j in ("pelvis", "head")}, motion, scene.frame_start)
    print(f"MMD ({'English' if english else 'Japanese'} names): feet and hands land within {error:.4f} of the "
          f"height, the head {head:.4f} (the rig's spine starts at its hips: no bone for our pelvis-spine1 step)")
    assert error < 0.032 and head < 0.052  # docs/animators.md: within 3.1%, the head 5.1%


def test_saved_bone_maps_keep_every_name_apart(scene, addon, tmp_path, monkeypatch):
    """A map's name is a name, not a file name: "Rig v1.2" is saved beside "Rig v1.1" (not as "Rig v1.json" over
    it); saving a name again replaces its own map; a name whose file is another map's is refused in one line."""
    monkeypatch.setattr(addon.rigchoice, "saved_maps_dir", lambda: tmp_path / "maps")
    props = scene.dancenet
    props.target, props.armature = "EXISTING", addon.rig.create_rig(bpy.context)
    for name in ("Rig v1.1", "Rig v1.2", "Rig v1.2"):
        assert bpy.ops.dancenet.save_bone_map(name=name) == {"FINISHED"}
    saved = {json.loads(p.read_text())["name"]: p.name for p in (tmp_path / "maps").iterdir()}
    assert saved == {"Rig v1.1": "Rig_v1.1.json", "Rig v1.2": "Rig_v1.2.json"}
    with pytest.raises(RuntimeError, match="'Rig v1.2' is saved as Rig_v1.2.json; choose another name"):
        bpy.ops.dancenet.save_bone_map(name="Rig_v1.2")
    assert json.loads((tmp_path / "maps" / "Rig_v1.2.json").read_text())["name"] == "Rig v1.2"
