"""The core skeleton laid out as Blender bones: heads, tails, rolls, frames. Pure numpy (no bpy).

The armature data stays in the core's frame (metres, +Y up, faces +Z, left +X) and the armature object
carries the Y-up -> Z-up turn, a +90 degree rotation about X: (x, y, z) -> (x, -z, y). Keeping the data
Y-up makes Blender's BVH exporter (which writes armature space as is) produce the usual Y-up BVH, and
the FBX exporter's own axis conversion cancels the object turn, so other tools get a clean rig.
"""

from __future__ import annotations

import math

import numpy as np

from dancenet_core.skeleton import Skeleton

# The armature object's rotation (Euler XYZ) and the matrix it applies: core frame -> Blender world.
OBJECT_ROTATION: tuple[float, float, float] = (math.pi / 2, 0.0, 0.0)
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

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

# Set on the armature data of rigs DanceNet builds (its own rules apply to them, e.g. a root bone at rest).
RIG_PROP = "dancenet_rig"
# Name and tail (core frame: on the floor, pointing forward) of the root bone a rig for root motion gets.
ROOT_BONE = "root"
ROOT_TAIL = (0.0, 0.0, 0.3)

# Joints a bone map must name (and the rig must have) for a dance to read as that dance.
REQUIRED_JOINTS: tuple[str, ...] = (
    "pelvis", "neck", "head",
    "left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle",
    "left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
)  # fmt: skip


# The spine between them: a rig needs a bone for one of these at least. Rigs of one family differ in their
# count of spine bones; the dance's turn of those a rig lacks is spread over those it has (keyframes.retarget).
SPINE_JOINTS: tuple[str, ...] = ("spine1", "spine2", "spine3")


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


def rest_heads(skeleton: Skeleton) -> np.ndarray:
    """Joint positions [J, 3] in the core frame with the feet on the floor (y = 0) in the rest pose."""
    return skeleton.rest_positions() + np.array([0.0, skeleton.rest_pelvis_height(), 0.0])


def roll_axes(tails: np.ndarray) -> np.ndarray:
    """Where each bone's local Z axis should point [J, 3] (core frame), for `EditBone.align_roll`.

    Upright bones (spine, legs) get Z toward the character's front (+Z); lying bones (arms, fingers,
    feet) get Z up (+Y), so left and right sides mirror and bending a knee or elbow is a local X turn.
    """
    d = tails / np.maximum(np.linalg.norm(tails, axis=1, keepdims=True), 1e-9)
    upright = np.abs(d[:, 1]) > 0.7
    return np.where(upright[:, None], np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]))


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
    """The smallest rotation [3, 3] taking direction a onto direction b."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = float(np.linalg.norm(axis)), float(a @ b)
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        # Opposite directions: half a turn about any axis perpendicular to a.
        helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        axis = np.cross(a, helper)
        s, c = 0.0, -1.0
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    angle = math.atan2(s, c)
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)
