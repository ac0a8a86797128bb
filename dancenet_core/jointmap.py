"""Another rig's clip on our 55-joint skeleton by a joint-name map, without a fit: the pieces of retargeting that
need no torch (a motion library build reads every clip with them, in Blender too: `armature_pose`;
`data/retarget.py` adds the position fit that the training data's CMU clips get).

A `JointMap` says which source joint each of our joints is; everything else (fingers, jaw, eyes) stays at rest.
1. The source's world pose (`source_pose`), turned so that its up axis is our +Y (found from the data: the head
   is above the pelvis) and scaled to metres.
2. A performer skeleton (`performer_skeleton`): our rest offsets with the source's bone lengths (left and right
   averaged, so the mirror augmentation stays exact), so the motion keeps the performer's reach and stride.
3. Each mapped joint given the source joint's world rotation (`initial_rotations`). For a BVH this assumes the
   source's rest pose is, like ours, a Y-up T-pose facing +Z (true of CMU/AMASS BVH and of our own BVH); a rig
   sampled in Blender (`armature_pose`) may rest in any pose, any way up: its turn from rest is carried onto our
   T-pose through each bone's rest direction (`bone_directions`, the same pairing the add-on keys rigs with).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from .bvh import BvhData
from .errors import DanceNetError
from .kinematics import fk_numpy
from .motion import Motion
from .rigmap import load_shipped
from .skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, MIRROR_INDEX, EndSite, Skeleton
from .units import DANCER_M, FILE_UNIT_NAMES, RIG_UNITS, dancer_unit


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


# CMU clips as AMASS writes them: the shipped CMU bone map (the 22 SMPL body joints under CMU's names).
CMU = JointMap("CMU", {j: str(b) for j, b in load_shipped("CMU").bones.items()})

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
    # [K, 3, 3]: per mapped joint the turn from our T-pose bone to the source's rest bone (None: the rests agree)
    rest_turns: np.ndarray | None = None


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
        # as the pelvis holds them in our T-pose (a rig's pelvis may rest turned from ours)
        back = np.eye(3) if source.rest_turns is None else source.rest_turns[source.joints.index(0)]
        side = [(rest_src[h] - rest_src[0]) @ back for h in hips]
        hip = 0.5 * (side[0] + side[1] * [-1, 1, 1])
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


def rotation_motion(source: SourcePose) -> Motion:
    """The source clip on its performer's skeleton (`performer_skeleton`), each mapped joint given the source
    joint's world rotation (`initial_rotations`) and the pelvis put where the source's is: a library clip as it is
    kept, and where the dataset's position fit starts."""
    skeleton = performer_skeleton(source)
    root = source.positions[:, source.joints.index(JOINT_INDEX["pelvis"])] - skeleton.offsets[0]
    return Motion(initial_rotations(source), root, source.fps, skeleton)


# Joints with several children: the one the bone points at (and whose direction a retarget matches).
_MAIN_CHILD = {
    "pelvis": "spine1",
    "spine3": "neck",
    "left_wrist": "left_middle1",
    "right_wrist": "right_middle1",
}
# Joints whose bone axis says more than any child (the head's children are the jaw and the eyes).
_NO_DIRECTION_CHILD = frozenset({"head"})
# Eyes look forward rather than continuing the head-to-eye offset.
_TAIL_OVERRIDE = {"left_eye_smplhf": (0.0, 0.0, 0.025), "right_eye_smplhf": (0.0, 0.0, 0.025)}


def direction_child(skeleton: Skeleton, j: int) -> int | None:
    """The child joint whose direction bone j follows, or None when the bone's own axis is used."""
    name = skeleton.names[j]
    if name in _NO_DIRECTION_CHILD:
        return None
    if name in _MAIN_CHILD:
        return skeleton.index(_MAIN_CHILD[name])
    children = skeleton.children(j)
    return children[0] if len(children) == 1 else None


def tail_offsets(skeleton: Skeleton) -> np.ndarray:
    """Bone vectors head -> tail [J, 3] in the core frame.

    An end site (head top, toe end, palm centre) if the joint has one, else the main child, else the
    joint's own offset direction (finger tips, jaw) at 80% of its length, at least 2 cm.
    """
    ends: dict[int, np.ndarray] = {}
    for site in skeleton.end_sites:
        ends.setdefault(site.parent, np.asarray(site.offset, dtype=np.float64))
    tails = np.zeros((skeleton.num_joints, 3))
    for j, name in enumerate(skeleton.names):
        child = direction_child(skeleton, j)
        if name in _TAIL_OVERRIDE:
            tails[j] = _TAIL_OVERRIDE[name]
        elif j in ends:
            tails[j] = ends[j]
        elif child is not None:
            tails[j] = skeleton.offsets[child]
        else:
            own = skeleton.offsets[j]
            length = max(0.8 * float(np.linalg.norm(own)), 0.02)
            tails[j] = own / max(float(np.linalg.norm(own)), 1e-9) * length
    return tails


def character_frame(
    left_hip: np.ndarray, right_hip: np.ndarray, pelvis: np.ndarray, neck: np.ndarray
) -> np.ndarray:
    """Orthonormal frame [3, 3] with columns (left, up, forward) from four rest joint positions.

    Retargeting compares two rigs through these frames, so a rig that faces another way or is stored
    Y-up (Mixamo imports) still dances facing its own front. Up is the world axis nearest the spine: a rig
    stands along one, and a spine that leans at rest (Rigify's by 6 degrees more than ours) is posture; taken
    as up, it would tilt the whole dance, its floor and the feet on it included.
    """
    spine = neck - pelvis
    axis = int(np.argmax(np.abs(spine)))
    up = np.sign(spine[axis]) * np.eye(3)[axis]
    left = left_hip - right_hip
    left = left - (left @ up) * up
    left = left / np.linalg.norm(left)
    return np.stack([left, up, np.cross(left, up)], axis=1)


def min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotations [..., 3, 3] taking directions a [..., 3] onto directions b [..., 3] (Rodrigues:
    I + K + K^2 / (1 + cos), K the cross product's matrix). Opposite directions, where that has no answer:
    half a turn about an axis perpendicular to a."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    a, b = np.broadcast_arrays(a, b)
    v = np.cross(a, b)
    cos = np.einsum("...i,...i->...", a, b)
    opposite = cos < -1.0 + 1e-9
    k = np.zeros((*v.shape, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k -= np.swapaxes(k, -1, -2)
    out = np.eye(3) + k + k @ k / np.where(opposite, 1.0, 1.0 + cos)[..., None, None]
    if opposite.any():
        helper = np.where(np.abs(a[opposite][:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        n = np.cross(a[opposite], helper)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        out[opposite] = 2.0 * n[:, :, None] * n[:, None, :] - np.eye(3)
    return out


def _chain_child(skeleton: Skeleton, j: int, mapped: set[int] | dict[int, object]) -> int | None:
    """The mapped joint bone j points at: its direction child, or, when the rig has no bone for that one (a spine
    of fewer bones), the first mapped joint further along the same chain."""
    child = direction_child(skeleton, j)
    while child is not None and child not in mapped:
        child = direction_child(skeleton, child)
    return child


class BonePair(NamedTuple):
    """A rig's bone against ours at rest: the direction it points in our rest pose (our frame) and at the rig's
    rest (the rig's frame); the mapped joint it points at (None: along its own axis), and that joint again if the
    bone reaches it past joints the rig has no bone for (else None)."""

    ours: np.ndarray
    theirs: np.ndarray
    child: int | None
    reach: int | None


def bone_directions(skeleton: Skeleton, heads: dict[int, np.ndarray], axes: dict[int, np.ndarray]
                    ) -> dict[int, BonePair]:
    """How a rig's rest pose pairs with ours, bone by bone, for each joint the rig has a bone for (`heads`: the
    bone's rest head, `axes`: its rest axis head -> tail, in the rig's frame). A bone points at the next mapped
    joint along its chain that does not start where it does (MMD's upper body starts at its parent); one that
    ends a chain (the head, a hand without fingers) points along its own axis. Keying a dance onto a rig (the
    add-on) and reading a rig's clip back (`armature_pose`) turn through the same pairs, so the one undoes the
    other."""
    ours = skeleton.rest_positions()
    ours_axis = tail_offsets(skeleton)
    out: dict[int, BonePair] = {}
    for j in heads:
        first = child = _chain_child(skeleton, j, heads)
        while child is not None and np.linalg.norm(heads[child] - heads[j]) <= 1e-6:
            child = _chain_child(skeleton, child, heads)
        if child is None:
            out[j] = BonePair(ours_axis[j], np.asarray(axes[j], dtype=np.float64), None, None)
        else:
            reach = child if child == first != direction_child(skeleton, j) else None
            out[j] = BonePair(ours[child] - ours[j], heads[child] - heads[j], child, reach)
    return out


def rest_turns(skeleton: Skeleton, heads: dict[int, np.ndarray], axes: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """Per joint a rig has a bone for (as `bone_directions` takes them), the turn [3, 3] from our T-pose bone to
    the rig's rest bone: the smallest that points it the rig's way; at a joint where the body branches (the pelvis,
    the chest, a hand with fingers), also turned about that direction as the other branches best agree (a rest pose
    whose chest is twisted, as an FBX file's first frame may be, would otherwise swing the collars around)."""
    pairs = bone_directions(skeleton, heads, axes)
    ours = skeleton.rest_positions()
    turns = {}
    for j, pair in pairs.items():
        others = [k for k in heads if k != pair.child and mapped_ancestor(k, heads.keys()) == j
                  and np.linalg.norm(heads[k] - heads[j]) > 1e-6]
        if pair.child is None or not others:
            turns[j] = min_rotation(pair.ours, pair.theirs)
            continue
        theirs = [pair.theirs, *(heads[k] - heads[j] for k in others)]
        mine = [pair.ours, *(ours[k] - ours[j] for k in others)]
        turns[j] = Rotation.align_vectors(theirs, mine, weights=[np.inf] + [1.0] * len(others))[0].as_matrix()
    return turns


def rotation_part(m: np.ndarray) -> np.ndarray:
    """The rotation part [..., 3, 3] of matrices [..., 4, 4] (or [..., 3, 3]), a bone's stretch or the object's
    scale taken out."""
    r = m[..., :3, :3]
    return r / np.linalg.norm(r, axis=-2, keepdims=True)


def armature_pose(joints: list[int], rest: np.ndarray, pose: np.ndarray, fps: float, name: str) -> SourcePose:
    """A rig's clip as sampled in Blender, on our terms: `joints` our joints the rig has bones for, `rest`
    [K, 4, 4] each one's bone's world rest matrix and `pose` [T, K, 4, 4] its world matrix per frame (Blender's
    bone convention: the head at the translation, the Y axis along the bone; the object's scale included),
    at `fps`. Any up axis and facing (read from the rest pose: the spine is up, the hips say left), any rest pose:
    our joint's world rotation is the bone's turn from its rest, then our T-pose bone turned onto the rig's rest
    bone (`rest_turns`), so an A-pose rest (Rigify's metarig, MPFB, CC) reads as right as a T-pose. Lengths are
    read in the unit that makes the rig a dancer's size (`rest_unit`)."""
    need = [n for n in ("pelvis", "left_hip", "right_hip", "neck") if JOINT_INDEX[n] not in joints]
    if need:
        raise RetargetError(f"{name}: a rig's clip needs bones for the pelvis, hips and neck; missing: "
                            f"{', '.join(need)}")
    order = sorted(range(len(joints)), key=lambda k: joints[k])  # parents first
    ours = [joints[k] for k in order]
    rest, pose = np.asarray(rest, dtype=np.float64)[order], np.asarray(pose, dtype=np.float64)[:, order]
    heads = rest[:, :3, 3]
    col = {j: k for k, j in enumerate(ours)}
    frame = character_frame(*(heads[col[JOINT_INDEX[n]]] for n in ("left_hip", "right_hip", "pelvis", "neck")))
    to_ours = frame.T  # the rig's world -> ours: its left, up and front become our +X, +Y and +Z
    metres = rest_unit(heads @ to_ours.T, ours, name)
    rest_heads = heads @ to_ours.T * metres
    axes = rotation_part(rest)[:, :, 1] @ to_ours.T
    turn = rest_turns(DEFAULT_SKELETON, {j: rest_heads[k] for k, j in enumerate(ours)},
                      {j: axes[k] for k, j in enumerate(ours)})
    turns = np.stack([turn[j] for j in ours])
    from_rest = to_ours @ rotation_part(pose) @ np.swapaxes(rotation_part(rest), -1, -2) @ to_ours.T
    return SourcePose(ours, pose[..., :3, 3] @ to_ours.T * metres, from_rest @ turns, rest_heads, fps, turns)


def rest_unit(heads: np.ndarray, joints: list[int], name: str) -> float:
    """Metres per unit of a rig's rest pose (`heads` [K, 3] of our `joints`, Y up): the one of `units.RIG_UNITS`
    that makes it nearest our dancer's size, for a file in centimetres, millimetres or inches, or an FBX rig whose
    0.01 scale was applied twice or not at all; a one-line RetargetError when none makes it a dancer's height."""
    height = float(np.ptp(heads[:, 1]))
    ours = float(np.ptp(DEFAULT_SKELETON.rest_positions()[joints, 1]))
    metres = dancer_unit(height, ours, RIG_UNITS)
    if not DANCER_M[0] < height * metres < DANCER_M[1]:
        raise RetargetError(f"{name}: the rig's rest pose is {height:.3g} units tall, which no unit "
                            f"({FILE_UNIT_NAMES}) makes a dancer's {DANCER_M[0]:g}-{DANCER_M[1]:g} m")
    return metres
