"""Our motion written as BVH in other tools' skeleton conventions, through a retargeting of our own: their bone
names (the shipped bone maps' and others'), their trees (a root bone on the floor, twist and in-between bones, end
bones, MMD's upper body beside its lower body), their rest pose (an A-pose: the offsets turned, each bone's rotation
turned back so the body is where ours is), unit, up axis, frame rate, a T-pose frame an exporter prepends. The
library must read each back onto our skeleton as the dance it is (tests/library/test_source_conventions.py,
scripts/convention_clips.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from dancenet_core.bvh import BvhData
from dancenet_core.jointmap import tail_offsets
from dancenet_core.kinematics import fk_numpy
from dancenet_core.motion import Motion
from dancenet_core.rigmap import load_shipped
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_NAMES, EndSite

Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # our Y-up frame -> a Z-up world
INCH = 0.0254


@dataclass(frozen=True)
class Convention:
    """A skeleton convention: `bones` our joint -> its bone (joints left out are not in its skeleton), `parents`
    bone -> parent where its tree is not ours, `root` a bone on the floor carrying the travel, `between` our
    joint -> a bone halfway from its parent's to it, `ends` our joint -> a leaf bone past it; the rest arms
    lowered `a_pose_deg`, metres per `unit`, Z up, at `fps`, a rest frame first (`t_pose`), the rest Y up but
    the motion's world Z up as AMASS writes CMU (`amass`), channels in `order`."""

    bones: dict[str, str]
    parents: dict[str, str] = field(default_factory=dict)
    root: str | None = None
    between: dict[str, str] = field(default_factory=dict)
    ends: dict[str, str] = field(default_factory=dict)
    a_pose_deg: float = 0.0
    unit: float = 1.0
    z_up: bool = False
    fps: float = 30.0
    t_pose: bool = False
    amass: bool = False
    order: str = "ZXY"


def shipped(key: str, body_only: bool = False, fingers: tuple[str, ...] | None = None,
            strip: str | None = None, which: int = 0) -> dict[str, str]:
    """Our joint -> the `which`-th name (else the first) a shipped map gives it; only the body joints, or those and
    the `fingers` named; the prefix `strip` taken off."""
    out = {}
    for joint, names in load_shipped(key).bones.items():
        names = [names] if isinstance(names, str) else names
        finger = next((f for f in ("thumb", "index", "middle", "ring", "pinky") if f in joint), None)
        if (body_only and JOINT_NAMES.index(joint) >= BODY_JOINTS and finger is None) or (
                finger is not None and fingers is not None and finger not in fingers):
            continue
        name = names[which] if which < len(names) else names[0]
        out[joint] = name.removeprefix(strip) if strip else name
    return out


def _generic() -> dict[str, str]:
    """Plain body-part names as many BVH tools write them: Hips, Spine, Chest, LeftUpLeg, ..."""
    names = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Chest", "neck": "Neck", "head": "Head"}
    for side, cap in (("left", "Left"), ("right", "Right")):
        names |= {f"{side}_hip": f"{cap}UpLeg", f"{side}_knee": f"{cap}Leg", f"{side}_ankle": f"{cap}Foot",
                  f"{side}_foot": f"{cap}Toe", f"{side}_collar": f"{cap}Shoulder", f"{side}_shoulder": f"{cap}Arm",
                  f"{side}_elbow": f"{cap}ForeArm", f"{side}_wrist": f"{cap}Hand"}  # fmt: skip
    return names


def _mixamo_ends(prefix: str, fingers: tuple[str, ...]) -> dict[str, str]:
    ends = {"head": f"{prefix}HeadTop_End"}
    for side, cap in (("left", "Left"), ("right", "Right")):
        ends |= {f"{side}_{f}3": f"{prefix}{cap}Hand{f.title()}4" for f in fingers}
    return ends


FINGERS = ("thumb", "index", "middle", "ring", "pinky")
MMD = shipped("MMD", body_only=True)
CONVENTIONS: dict[str, Convention] = {
    "mixamo": Convention(shipped("MIXAMO"), ends=_mixamo_ends("mixamorig:", FINGERS), unit=0.01),
    "mixamo_bare": Convention(shipped("MIXAMO", fingers=("thumb", "index"), strip="mixamorig:"),
                              ends=_mixamo_ends("", ("thumb", "index")), unit=0.01, fps=60.0, order="XYZ"),
    "mixamo1_handless": Convention({j: b.replace("mixamorig:", "mixamorig1:") for j, b in
                                    shipped("MIXAMO", body_only=True).items()}, a_pose_deg=10.0),
    "vrm": Convention(shipped("VRM"), a_pose_deg=30.0, fps=60.0),
    "vrm_humanoid": Convention(shipped("VRM", which=1), unit=0.01),
    "unreal": Convention(shipped("UNREAL"), root="root", between={"spine2": "spine_02", "spine3": "spine_04",
                         "left_elbow": "upperarm_twist_01_l"}, a_pose_deg=40.0, unit=0.01, z_up=True, fps=60.0),
    "character_creator": Convention(shipped("CC"), root="CC_Base_BoneRoot", between={"head": "CC_Base_NeckTwist02"},
                                    a_pose_deg=45.0, unit=0.01, t_pose=True),
    "rokoko": Convention(shipped("ROKOKO"), between={"spine3": "Spine3"}, ends={"head": "HeadEnd"}, fps=120.0),
    "xsens": Convention(shipped("XSENS"), between={"spine3": "Chest3"}, unit=0.01, fps=60.0),
    "motive": Convention(shipped("MOTIVE"), fps=120.0, order="YXZ"),
    "daz": Convention(shipped("DAZ"), between={"left_knee": "lThighTwist", "right_knee": "rThighTwist",
                      "left_elbow": "lShldrTwist", "right_elbow": "rShldrTwist"}, a_pose_deg=45.0, unit=0.01),
    "mmd": Convention(MMD, parents={MMD["spine1"]: "センター"}, root="センター", a_pose_deg=35.0, unit=INCH),
    "rigify": Convention(shipped("RIGIFY"), root="root", between={"head": "DEF-spine.005"}, z_up=True),
    "metarig": Convention(shipped("METARIG", fingers=()), between={"head": "spine.005"}, a_pose_deg=20.0,
                          z_up=True, unit=0.001),
    "mpfb": Convention(shipped("MPFB"), a_pose_deg=25.0, unit=0.01, z_up=True, fps=25.0),
    "generic": Convention(_generic(), ends={"head": "HeadEnd"}, unit=0.01, t_pose=True, fps=24.0),
    "generic_sided": Convention(shipped("GENERIC", body_only=True), a_pose_deg=15.0, order="YXZ"),
    "cmu": Convention(shipped("CMU"), amass=True),
    "ours_z_up_mm": Convention({j: j for j in JOINT_NAMES}, z_up=True, unit=0.001, fps=120.0),
}


def rest_pose(a_pose_deg: float) -> np.ndarray:
    """Our local rotations [55, 3] of a rest pose whose arms are lowered by `a_pose_deg` (a T-pose at 0)."""
    rot = np.zeros((DEFAULT_SKELETON.num_joints, 3))
    a = math.radians(a_pose_deg)
    rot[JOINT_NAMES.index("left_shoulder")], rot[JOINT_NAMES.index("right_shoulder")] = (0, 0, -a), (0, 0, a)
    return rot


def as_convention(motion: Motion) -> Motion:
    """`motion` with the joints no convention has held still (our spine3, which the generic names lack) — a
    convention without a bone for a joint cannot turn it."""
    rot = motion.rotations.copy()
    rot[:, JOINT_NAMES.index("spine3")] = 0.0
    return Motion(rot, motion.root_positions, motion.fps, motion.skeleton)


def convention_bvh(motion: Motion, conv: Convention) -> BvhData:
    """`motion` (on our skeleton) danced by a skeleton of `conv`, as a BVH of that tool would hold it: the
    convention's bones at our joints' places (their rest offsets from an A-pose where it has one), each turned
    so that the body is where `motion` puts it."""
    s = motion.skeleton
    m = motion.resampled(conv.fps) if conv.fps != motion.fps else motion
    rest_p, rest_r = (a[0] for a in fk_numpy(s, rest_pose(conv.a_pose_deg)[None], np.zeros((1, 3))))
    rest_p = rest_p + [0.0, s.rest_pelvis_height(), 0.0]
    pos, rot = fk_numpy(s, m.rotations, m.root_positions)
    rot = rot @ np.swapaxes(rest_r, -1, -2)[None]  # each bone's world turn: ours, less its rest turn
    tails = tail_offsets(s)
    # (name, parent, rest head, world positions [T, 3], world rotations [T, 3, 3])
    bones: list[tuple[str, str | None, np.ndarray, np.ndarray, np.ndarray]] = []
    where: dict[int, str] = {}
    if conv.root is not None:
        ground = pos[:, 0] * [1.0, 0.0, 1.0]
        bones.append((conv.root, None, np.zeros(3), ground, np.broadcast_to(np.eye(3), rot[:, 0].shape)))
    for j, name in enumerate(s.names):
        p = s.parents[j]
        while p >= 0 and p not in where:
            p = s.parents[p]
        parent = where.get(p, conv.root)
        if name in conv.between and parent is not None:
            k = next(i for i, b in enumerate(bones) if b[0] == parent)
            head = (bones[k][2] + rest_p[j]) / 2
            at = bones[k][3] + np.einsum("tij,j->ti", bones[k][4], head - bones[k][2])
            bones.append((conv.between[name], parent, head, at, bones[k][4]))
            parent = conv.between[name]
        if name not in conv.bones:
            continue
        bone = conv.bones[name]
        bones.append((bone, conv.parents.get(bone, parent), rest_p[j], pos[:, j], rot[:, j]))
        where[j] = bone
        if name in conv.ends:
            tail = rest_r[j] @ tails[j]
            bones.append((conv.ends[name], bone, rest_p[j] + tail, pos[:, j] + np.einsum("tij,j->ti", rot[:, j], tail),
                          rot[:, j]))  # fmt: skip
    return _bvh(bones, conv, m.num_frames)


def _bvh(bones: list, conv: Convention, frames: int) -> BvhData:
    turn = Z_UP if conv.z_up or conv.amass else np.eye(3)
    rest_turn = Z_UP if conv.z_up else np.eye(3)
    index = {b[0]: i for i, b in enumerate(bones)}
    parents = tuple(index[b[1]] if b[1] is not None else -1 for b in bones)
    heads = np.array([b[2] for b in bones]) @ rest_turn.T
    offsets = np.array([heads[i] - (heads[p] if p >= 0 else 0.0) for i, p in enumerate(parents)]) / conv.unit
    world = np.stack([turn @ b[4] @ rest_turn.T for b in bones], axis=1)  # [T, B, 3, 3]
    local = np.stack([world[:, i] if p < 0 else np.swapaxes(world[:, p], -1, -2) @ world[:, i]
                      for i, p in enumerate(parents)], axis=1)  # fmt: skip
    euler = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_euler(conv.order, degrees=True).reshape(frames, -1, 3)
    # The root's place, and the hips' under a root bone (exporters key both): each in its parent's frame.
    moving = [0, 1] if conv.root is not None else [0]
    places = [bones[i][3] @ turn.T if parents[i] < 0 else np.einsum(
        "tji,tj->ti", world[:, parents[i]], (bones[i][3] - bones[parents[i]][3]) @ turn.T) for i in moving]
    places = [p / conv.unit for p in places]
    if conv.t_pose:
        euler = np.concatenate([np.zeros_like(euler[:1]), euler])
        places = [np.concatenate([offsets[i : i + 1], p]) for i, p in zip(moving, places, strict=True)]
    columns = [np.concatenate([places[i], euler[:, i]], axis=1) if i in moving else euler[:, i]
               for i in range(len(bones))]  # fmt: skip
    values = np.concatenate(columns, axis=1)
    rotations = tuple(f"{axis}rotation" for axis in conv.order)
    channels = tuple(("Xposition", "Yposition", "Zposition", *rotations) if i in moving else rotations
                     for i in range(len(bones)))  # fmt: skip
    leaves = sorted(set(range(len(bones))) - set(parents))
    sites = tuple(EndSite(f"{bones[i][0]}_end", i, tuple(0.5 * offsets[i])) for i in leaves)
    return BvhData(tuple(b[0] for b in bones), parents, offsets, channels, sites, 1.0 / conv.fps, values)

