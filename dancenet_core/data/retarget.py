"""Retarget a BVH clip from another rig onto our 55-joint skeleton, by a joint-name map.

The same mechanism serves the CMU dance clips and, later, users' rigs in the add-on: a `JointMap` says
which source joint each of our joints is; everything else (fingers, jaw, eyes) stays at rest.

Three steps:
1. The source's world pose, turned so that its up axis is our +Y (found from the data: the head is
   above the pelvis) and scaled to metres.
2. A performer skeleton: our rest offsets with the source's bone lengths (left and right averaged, so
   the mirror augmentation stays exact), so the motion keeps the performer's reach and stride.
3. Rotations fitted so that our joints land on the source's joints (`data.fit.optimise_rotations`, the
   same fit as the Dance with Melody markers). Positions leave the turn of end joints open (head, hands,
   feet), so each end joint also gets two points that turn with the source joint; this, and the start of
   the fit, assume the source's rest pose is, like ours, a Y-up T-pose facing +Z (true of CMU/AMASS
   BVH and of our own BVH).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..bvh import BvhData
from ..errors import DanceNetError
from ..kinematics import fk_numpy
from ..motion import Motion
from ..skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, MIRROR_INDEX, EndSite, Skeleton
from .fit import Target, fit_errors, optimise_rotations, target_positions


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
_TURN_POINT = 0.1  # metres from an end joint to each of its two turn points


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


@dataclass
class Retargeted:
    """A retargeted clip: our motion, the source it was fitted to, and the points fitted."""

    motion: Motion
    source: SourcePose
    targets: list[Target]

    def errors(self) -> np.ndarray:
        """Per-frame distances (metres) between our joints and the source's, [T, K] (mapped joints)."""
        return fit_errors(self.motion, _points(self.source, self.targets), self.targets)


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


def _pinned(j: int, mapped: set[int]) -> bool:
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
        if p >= 0 and not _pinned(j, mapped):
            scale[j] = scale[p]  # past the mapped joints: the parent bone's scale
    ends = tuple(EndSite(e.name, e.parent, tuple(float(v) for v in np.array(e.offset) * scale[e.parent]))
                 for e in DEFAULT_SKELETON.end_sites)
    offsets = DEFAULT_SKELETON.offsets * scale[:, None]
    hips = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]
    if all(j in mapped and mapped_ancestor(j, mapped) == 0 for j in hips):
        hip = 0.5 * (rest_src[hips[0]] - rest_src[0] + (rest_src[hips[1]] - rest_src[0]) * [-1, 1, 1])
        offsets[hips] = [hip, hip * [-1, 1, 1]]
    return Skeleton(offsets, end_sites=ends)


def _end_joints(joints: list[int]) -> list[int]:
    return [j for j in joints if not any(mapped_ancestor(c, set(joints)) == j for c in joints)]


def fit_targets(source: SourcePose) -> list[Target]:
    """One target per mapped joint (points 0..K-1), then two turn points per end joint."""
    targets = [Target(DEFAULT_SKELETON.names[j], j, (0.0, 0.0, 0.0), (k,)) for k, j in enumerate(source.joints)]
    n = len(source.joints)
    for j in _end_joints(source.joints):
        for axis in (0, 2):  # two points off the joint in different directions fix its whole turn
            offset = [0.0, 0.0, 0.0]
            offset[axis] = _TURN_POINT
            targets.append(Target(f"{DEFAULT_SKELETON.names[j]}_turn{'xyz'[axis]}", j, tuple(offset), (n,),
                                  0.3, matched=False))
            n += 1
    return targets


def _points(source: SourcePose, targets: list[Target]) -> np.ndarray:
    """The source side of every target, [T, P, 3]: joints, then turn points carried by the joints' rotations."""
    col = {j: k for k, j in enumerate(source.joints)}
    extra = [source.positions[:, col[t.joint]] + source.rotations[:, col[t.joint]] @ np.array(t.offset)
             for t in targets if not t.matched]
    return np.concatenate([source.positions, np.stack(extra, axis=1)], axis=1)


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


def retarget(data: BvhData, joint_map: JointMap, fps: float, steps: int = 200, path: str = "BVH") -> Retargeted:
    """Our skeleton doing the clip `data`, at `fps`, fitted to the source joints' world positions."""
    source = source_pose(data, joint_map, fps, path)
    skeleton = performer_skeleton(source)
    targets = fit_targets(source)
    mapped = set(source.joints)
    # Body joints that nothing pins (no mapped joint below them) keep the start rotation.
    frozen = [j for j in range(BODY_JOINTS) if not _pinned(j, mapped)]
    root0 = source.positions[:, source.joints.index(0)] - skeleton.offsets[0]
    motion = optimise_rotations(skeleton, targets, target_positions(_points(source, targets), targets),
                                initial_rotations(source), root0, fps, frozen, steps)
    return Retargeted(motion, source, targets)
