"""The core skeleton laid out as Blender bones: heads, rolls, the object's turn (tails, bone directions and
character frames, which reading a rig's clip needs too, are in `dancenet_core.jointmap`). Pure numpy (no bpy).

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

# Set on the armature data of rigs DanceNet builds (its own rules apply to them, e.g. a root bone at rest).
RIG_PROP = "dancenet_rig"
# Name and tail (core frame: on the floor, pointing forward) of the root bone a rig for root motion gets.
ROOT_BONE = "root"
ROOT_TAIL = (0.0, 0.0, 0.3)

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
