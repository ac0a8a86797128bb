"""The 55-joint skeleton (SMPL-X joint order and names) with our own rest offsets.

Frame convention: metres, +Y up, the character faces +Z in its rest pose, its left side is +X
(the SMPL convention). The rest pose is a T-pose. Offsets are our own numbers, sized after the
median bone lengths of the Dance with Melody capture (a 1.70 m dancer), not taken from any model file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "jaw", "left_eye_smplhf", "right_eye_smplhf",
    "left_index1", "left_index2", "left_index3", "left_middle1", "left_middle2", "left_middle3",
    "left_pinky1", "left_pinky2", "left_pinky3", "left_ring1", "left_ring2", "left_ring3",
    "left_thumb1", "left_thumb2", "left_thumb3",
    "right_index1", "right_index2", "right_index3", "right_middle1", "right_middle2", "right_middle3",
    "right_pinky1", "right_pinky2", "right_pinky3", "right_ring1", "right_ring2", "right_ring3",
    "right_thumb1", "right_thumb2", "right_thumb3",
)  # fmt: skip

PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 15, 15, 15,
    20, 25, 26, 20, 28, 29, 20, 31, 32, 20, 34, 35, 20, 37, 38,
    21, 40, 41, 21, 43, 44, 21, 46, 47, 21, 49, 50, 21, 52, 53,
)  # fmt: skip

NUM_JOINTS = len(JOINT_NAMES)
JOINT_INDEX: dict[str, int] = {n: i for i, n in enumerate(JOINT_NAMES)}
# The SMPL body joints 0..21 (hands follow): what the fit, the metrics and the motion style net read.
# Every parent precedes its child.
BODY_JOINTS = 22

# Left-side offsets; the right side is their mirror (x -> -x).
_BODY_LEFT: dict[str, tuple[float, float, float]] = {
    "left_hip": (0.09, -0.08, 0.0),
    "left_knee": (0.0, -0.40, 0.0),
    "left_ankle": (0.0, -0.41, -0.02),
    "left_foot": (0.0, -0.04, 0.12),
    "left_collar": (0.07, 0.12, -0.01),
    "left_shoulder": (0.11, 0.03, -0.01),
    "left_elbow": (0.26, 0.0, 0.0),
    "left_wrist": (0.25, 0.0, 0.0),
    "left_eye_smplhf": (0.03, 0.06, 0.08),
}
_CENTRE: dict[str, tuple[float, float, float]] = {
    "pelvis": (0.0, 0.0, 0.0),
    "spine1": (0.0, 0.11, -0.02),
    "spine2": (0.0, 0.13, 0.0),
    "spine3": (0.0, 0.06, 0.02),
    "neck": (0.0, 0.21, -0.02),
    "head": (0.0, 0.09, 0.04),
    "jaw": (0.0, -0.03, 0.05),
}
# Fingers, from the wrist along +X (left hand), in the order (first, second, third) segment.
_FINGERS_LEFT: dict[str, tuple[tuple[float, float, float], ...]] = {
    "index": ((0.09, 0.0, 0.025), (0.035, 0.0, 0.0), (0.025, 0.0, 0.0)),
    "middle": ((0.095, 0.0, 0.005), (0.04, 0.0, 0.0), (0.027, 0.0, 0.0)),
    "pinky": ((0.08, 0.0, -0.04), (0.025, 0.0, 0.0), (0.02, 0.0, 0.0)),
    "ring": ((0.09, 0.0, -0.018), (0.035, 0.0, 0.0), (0.025, 0.0, 0.0)),
    "thumb": ((0.025, -0.01, 0.025), (0.03, 0.0, 0.02), (0.025, 0.0, 0.015)),
}


def _default_offsets() -> np.ndarray:
    off = np.zeros((NUM_JOINTS, 3))
    for name, v in _CENTRE.items():
        off[JOINT_INDEX[name]] = v
    for name, v in _BODY_LEFT.items():
        off[JOINT_INDEX[name]] = v
        off[JOINT_INDEX[name.replace("left_", "right_")]] = (-v[0], v[1], v[2])
    for finger, segs in _FINGERS_LEFT.items():
        for k, v in enumerate(segs, start=1):
            off[JOINT_INDEX[f"left_{finger}{k}"]] = v
            off[JOINT_INDEX[f"right_{finger}{k}"]] = (-v[0], v[1], v[2])
    return off


@dataclass(frozen=True)
class EndSite:
    """A point rigidly attached to a joint (a BVH 'End Site'), used as an end-effector."""

    name: str
    parent: int
    offset: tuple[float, float, float]


# The paper's five end-effectors: toe ends, head end, and the two hands (palm centre).
END_EFFECTORS: tuple[EndSite, ...] = (
    EndSite("left_toe_end", JOINT_INDEX["left_foot"], (0.0, -0.02, 0.06)),
    EndSite("right_toe_end", JOINT_INDEX["right_foot"], (0.0, -0.02, 0.06)),
    EndSite("head_end", JOINT_INDEX["head"], (0.0, 0.16, 0.0)),
    EndSite("left_hand", JOINT_INDEX["left_wrist"], (0.08, 0.0, 0.0)),
    EndSite("right_hand", JOINT_INDEX["right_wrist"], (-0.08, 0.0, 0.0)),
)
TOE_ENDS = (0, 1)  # indices into END_EFFECTORS

# Left/right joint pairs, for mirroring motion.
MIRROR_INDEX: tuple[int, ...] = tuple(
    JOINT_INDEX[
        n.replace("left_", "@").replace("right_", "left_").replace("@", "right_")
        if ("left_" in n or "right_" in n)
        else n
    ]
    for n in JOINT_NAMES
)

# The lower body (root and legs), which the Foot Constraint Model corrects.
LOWER_BODY: tuple[int, ...] = tuple(
    JOINT_INDEX[n]
    for n in ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee",
              "left_ankle", "right_ankle", "left_foot", "right_foot")
)  # fmt: skip


@dataclass
class Skeleton:
    """Joint hierarchy with rest offsets (each joint's position in its parent's frame, rest pose)."""

    offsets: np.ndarray = field(default_factory=_default_offsets)
    names: tuple[str, ...] = JOINT_NAMES
    parents: tuple[int, ...] = PARENTS
    end_sites: tuple[EndSite, ...] = END_EFFECTORS

    def __post_init__(self) -> None:
        self.offsets = np.asarray(self.offsets, dtype=np.float64)
        if self.offsets.shape != (len(self.names), 3):
            raise ValueError(f"offsets must have shape ({len(self.names)}, 3), got {self.offsets.shape}")
        for j, p in enumerate(self.parents):
            if p >= j:
                raise ValueError(f"joint {j} ({self.names[j]}) must come after its parent {p}")

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, j: int) -> list[int]:
        return [c for c, p in enumerate(self.parents) if p == j]

    def rest_positions(self) -> np.ndarray:
        """World positions of the joints in the rest pose, pelvis at the origin."""
        pos = np.zeros_like(self.offsets)
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] if p < 0 else pos[p] + self.offsets[j]
        return pos

    def end_site_offsets(self) -> np.ndarray:
        return np.array([s.offset for s in self.end_sites], dtype=np.float64)

    def end_site_parents(self) -> np.ndarray:
        return np.array([s.parent for s in self.end_sites], dtype=np.int64)

    def feet(self) -> Skeleton:
        """The body's first BODY_JOINTS joints (no fingers, jaw or eyes) with only the toe end sites: all that the
        feet and the floor depend on, at under half the forward kinematics of the whole skeleton."""
        return Skeleton(self.offsets[:BODY_JOINTS], self.names[:BODY_JOINTS], self.parents[:BODY_JOINTS],
                        tuple(self.end_sites[i] for i in TOE_ENDS))

    def scaled(self, factor: float) -> Skeleton:
        return Skeleton(self.offsets * factor, self.names, self.parents, self.end_sites)

    def rest_pelvis_height(self) -> float:
        """Pelvis height that puts the lowest toe end on the floor in the rest pose."""
        rest = self.rest_positions()
        toes = rest[self.end_site_parents()[list(TOE_ENDS)]] + self.end_site_offsets()[list(TOE_ENDS)]
        return float(-toes[:, 1].min())


DEFAULT_SKELETON = Skeleton()
