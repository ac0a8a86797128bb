"""Another rig's clip on our 55-joint skeleton by a joint-name map, without a fit: the pieces of retargeting that
need no torch (a motion library build reads CMU clips with them in Blender; `data/retarget.py` adds the position
fit that the training data uses).

A `JointMap` says which source joint each of our joints is; everything else (fingers, jaw, eyes) stays at rest.
1. The source's world pose (`source_pose`), turned so that its up axis is our +Y (found from the data: the head
   is above the pelvis) and scaled to metres.
2. A performer skeleton (`performer_skeleton`): our rest offsets with the source's bone lengths (left and right
   averaged, so the mirror augmentation stays exact), so the motion keeps the performer's reach and stride.
3. Each mapped joint given the source joint's world rotation (`initial_rotations`). This assumes the source's
   rest pose is, like ours, a Y-up T-pose facing +Z (true of CMU/AMASS BVH and of our own BVH).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .bvh import BvhData
from .errors import DanceNetError
from .kinematics import fk_numpy
from .skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, MIRROR_INDEX, EndSite, Skeleton


class RetargetError(DanceNetError):
    """A clip that cannot be retargeted (its joint names do not match the map, or its units look wrong)."""


@dataclass(frozen=True)
class JointMap:
    """Our joint name -> the source rig's joint name, and the source's length unit in metres."""

    name: str
    joints: dict[str, str]
    scale: float = 1.0

    def __post_init__(self) -> None:
        unknown = [n for n in self.joints if n not in JOINT_INDEX or JOINT_INDEX[n] >= BODY_JOINTS]
        if unknown or "pelvis" not in self.joints or not {"head", "neck"} & set(self.joints):
            raise ValueError(f"joint map {self.name}: needs 'pelvis', 'head' or 'neck', and only our body joints; "
                             f"unknown: {unknown}")


# CMU clips as AMASS writes them: the 22 SMPL body joints under CMU's names. Their toe joint is the ball
# of the foot (our `foot`) and their upper neck is the head joint.
CMU = JointMap("CMU", {
    "pelvis": "root", "left_hip": "lhip", "right_hip": "rhip", "spine1": "lowerback",
    "left_knee": "lknee", "right_knee": "rknee", "spine2": "upperback", "left_ankle": "lankle",
    "right_ankle": "rankle", "spine3": "chest", "left_foot": "ltoe", "right_foot": "rtoe",
    "neck": "lowerneck", "left_collar": "lclavicle", "right_collar": "rclavicle", "head": "upperneck",
    "left_shoulder": "lshoulder", "right_shoulder": "rshoulder", "left_elbow": "lelbow",
    "right_elbow": "relbow", "left_wrist": "lwrist", "right_wrist": "rwrist",
})  # fmt: skip

# Rotations that turn a world whose up axis is (axis, sign) into our Y-up world.
_UP_TO_Y = {
    (1, 1.0): Rotation.identity(),
    (1, -1.0): Rotation.from_euler("x", 180, degrees=True),
    (2, 1.0): Rotation.from_euler("x", -90, degrees=True),
    (2, -1.0): Rotation.from_euler("x", 90, degrees=True),
    (0, 1.0): Rotation.from_euler("z", 90, degrees=True),
    (0, -1.0): Rotation.from_euler("z", -90, degrees=True),
}


@dataclass
class SourcePose:
    """The source clip on our terms: metres, Y up, at our frame rate, only the mapped joints.

    joints: our joint index of each mapped joint (parents first); positions [T, K, 3] and world
    rotations [T, K, 3, 3] of the source joints; rest [K, 3] their rest positions (metres).
    """

    joints: list[int]
    positions: np.ndarray
    rotations: np.ndarray
    rest: np.ndarray
    fps: float


def check_names(data: BvhData, joint_map: JointMap, path: str) -> None:
    """Raise a one-line `RetargetError` naming the map's source joints that the BVH lacks."""
    missing = [s for s in joint_map.joints.values() if s not in data.names]
    if missing:
        raise RetargetError(f"{path}: the BVH joints do not match the {joint_map.name} joint map; "
                            f"missing: {', '.join(missing)} (the file has: {', '.join(data.names)})")


def up_rotation(positions: np.ndarray, pelvis: int, head: int) -> Rotation:
    """The turn that makes the source's up axis (the signed axis nearest head minus pelvis) our +Y."""
    up = np.median(positions[:, head] - positions[:, pelvis], axis=0)
    axis = int(np.argmax(np.abs(up)))
    return _UP_TO_Y[(axis, float(np.sign(up[axis])))]


def source_pose(data: BvhData, joint_map: JointMap, fps: float, path: str = "BVH") -> SourcePose:
    """The mapped joints' world pose, resampled to `fps` (slerp on the source's own rotations)."""
    check_names(data, joint_map, path)
    src = data.to_motion(scale=joint_map.scale).resampled(fps)
    ours = sorted(JOINT_INDEX[n] for n in joint_map.joints)
    cols = [src.skeleton.index(joint_map.joints[DEFAULT_SKELETON.names[j]]) for j in ours]
    wp, wr = fk_numpy(src.skeleton, src.rotations, src.root_positions)
    rest = src.skeleton.rest_positions()[cols]
    height = float(np.ptp(rest[:, 1]))
    if not 0.5 < height < 2.5:
        raise RetargetError(f"{path}: the rest pose is {height:.3g} m tall after scaling by {joint_map.scale}; "
                            f"set the {joint_map.name} map's scale to the file's unit in metres")
    head = ours.index(JOINT_INDEX["head"] if "head" in joint_map.joints else JOINT_INDEX["neck"])
    turn = up_rotation(wp[:, cols], 0, head).as_matrix()
    return SourcePose(ours, wp[:, cols] @ turn.T, turn @ wr[:, cols], rest, fps)


def mapped_ancestor(j: int, mapped: set[int] | list[int]) -> int:
    """The nearest ancestor of our joint j that the map names (-1 for the root)."""
    p = DEFAULT_SKELETON.parents[j]
    while p >= 0 and p not in mapped:
        p = DEFAULT_SKELETON.parents[p]
    return p


def pinned(j: int, mapped: set[int]) -> bool:
    """Whether joint j is mapped or has a mapped joint below it (so the fit decides its rotation)."""
    for m in mapped:
        while m >= 0 and m != j:
            m = DEFAULT_SKELETON.parents[m]
        if m == j:
            return True
    return False


def performer_skeleton(source: SourcePose) -> Skeleton:
    """Our rest offsets, each chain between mapped joints scaled to the source's rest distance.

    The hips sit where the source's do (as the Dance with Melody fit places them from the markers): their
    direction from the pelvis differs between rigs by a few centimetres, which bone lengths cannot fix.
    Left and right are averaged (the mirror augmentation needs a symmetric skeleton); joints and end
    sites past the mapped ones (fingers, toe ends, head end) scale with their parent's bone.
    """
    rest_ours = DEFAULT_SKELETON.rest_positions()
    rest_src = {j: source.rest[k] for k, j in enumerate(source.joints)}
    mapped = set(source.joints)
    scale = np.ones(DEFAULT_SKELETON.num_joints)
    for j in source.joints:
        a = mapped_ancestor(j, mapped)
        if a < 0:
            continue
        k = np.linalg.norm(rest_src[j] - rest_src[a]) / np.linalg.norm(rest_ours[j] - rest_ours[a])
        c = j
        while c != a:
            scale[c] = k
            c = DEFAULT_SKELETON.parents[c]
    scale = 0.5 * (scale + scale[list(MIRROR_INDEX)])
    for j, p in enumerate(DEFAULT_SKELETON.parents):
        if p >= 0 and not pinned(j, mapped):
            scale[j] = scale[p]  # past the mapped joints: the parent bone's scale
    ends = tuple(EndSite(e.name, e.parent, tuple(float(v) for v in np.array(e.offset) * scale[e.parent]))
                 for e in DEFAULT_SKELETON.end_sites)
    offsets = DEFAULT_SKELETON.offsets * scale[:, None]
    hips = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]
    if all(j in mapped and mapped_ancestor(j, mapped) == 0 for j in hips):
        hip = 0.5 * (rest_src[hips[0]] - rest_src[0] + (rest_src[hips[1]] - rest_src[0]) * [-1, 1, 1])
        offsets[hips] = [hip, hip * [-1, 1, 1]]
    return Skeleton(offsets, end_sites=ends)


def initial_rotations(source: SourcePose) -> np.ndarray:
    """Local rotation vectors [T, 55, 3] that give each mapped joint the source joint's world rotation
    (the rest poses agree); unmapped joints stay at rest relative to their parent."""
    n = len(source.positions)
    world = np.repeat(np.eye(3)[None, None], DEFAULT_SKELETON.num_joints, axis=1).repeat(n, axis=0)
    col = {j: k for k, j in enumerate(source.joints)}
    local = np.zeros((n, DEFAULT_SKELETON.num_joints, 3))
    for j, p in enumerate(DEFAULT_SKELETON.parents):
        parent = world[:, p] if p >= 0 else np.eye(3)
        world[:, j] = source.rotations[:, col[j]] if j in col else parent
        local[:, j] = Rotation.from_matrix(np.swapaxes(parent, -1, -2) @ world[:, j]).as_rotvec()
    return local
