"""The paper's motion representation (section 4.3) and per-channel normalisation.

One frame's feature vector, in this order (see `FeatureLayout`):
  root:     dx, y, dz (translation delta in the previous frame's heading frame; absolute height),
            dyaw (heading change since the previous frame), tilt_x, tilt_z (the root rotation with its
            heading removed: a swing about a horizontal axis, as a rotation vector whose y part is 0)
  rotations: rotation vectors of joints 1..J-1 relative to their parents (3 each)
  end effectors: the skeleton's end sites relative to the root, in the current heading frame (3 each)
  contacts: left/right foot contact (0/1), from toe-end height and speed

Rotation vectors rather than the paper's Euler angles: same 3 numbers per joint, but no gimbal flips.
Decoding integrates the deltas in float64 from a given start heading and position, so a long clip comes
back without drift.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .atomic import atomic_open
from .kinematics import fk_numpy
from .motion import Motion
from .skeleton import DEFAULT_SKELETON, TOE_ENDS, Skeleton

# Contact: toe end within this height of the floor and moving slower than this (horizontal).
CONTACT_HEIGHT_M = 0.05
CONTACT_SPEED_MPS = 0.35


@dataclass(frozen=True)
class FeatureLayout:
    """Where each part of the feature vector sits, for a skeleton with J joints and E end sites."""

    num_joints: int
    num_end_sites: int

    @property
    def root(self) -> slice:
        return slice(0, 6)

    @property
    def rotations(self) -> slice:
        return slice(6, 6 + 3 * (self.num_joints - 1))

    @property
    def end_effectors(self) -> slice:
        s = self.rotations.stop
        return slice(s, s + 3 * self.num_end_sites)

    @property
    def contacts(self) -> slice:
        s = self.end_effectors.stop
        return slice(s, s + 2)

    @property
    def continuous(self) -> slice:
        """The channels the mixture density models (everything but contacts)."""
        return slice(0, self.end_effectors.stop)

    @property
    def size(self) -> int:
        return self.contacts.stop

    @classmethod
    def for_skeleton(cls, skeleton: Skeleton) -> FeatureLayout:
        return cls(skeleton.num_joints, len(skeleton.end_sites))


def heading(root_rotvecs: np.ndarray) -> np.ndarray:
    """The heading of root rotations [..., 3] as angles [N] in (-pi, pi]: the twist about +Y (swing-twist
    decomposition of the quaternion)."""
    q = Rotation.from_rotvec(np.reshape(root_rotvecs, (-1, 3))).as_quat()  # x, y, z, w
    return 2.0 * np.arctan2(q[:, 1], q[:, 3])


def yaw_and_swing(root_rotvecs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split root rotations R = Ry(yaw) @ S into unwrapped yaw [T] (`heading`) and swing S [T, 3] (S_y = 0)."""
    q = Rotation.from_rotvec(root_rotvecs).as_quat()
    yaw = np.unwrap(heading(root_rotvecs))
    # angles as (N, 1): newer scipy reads a 1-D array for one axis as a single rotation
    swing = (Rotation.from_euler("y", -yaw[:, None]) * Rotation.from_quat(q)).as_rotvec()
    return yaw, swing


def heading_frames(motion: Motion) -> np.ndarray:
    """Unwrapped heading (yaw about +Y) of the root, per frame."""
    return yaw_and_swing(motion.rotations[:, 0])[0]


def foot_contacts(
    toe_positions: np.ndarray,
    fps: float,
    floor: float | None = None,
    height: float = CONTACT_HEIGHT_M,
    speed: float = CONTACT_SPEED_MPS,
) -> np.ndarray:
    """Contact flags [T, 2] for toe-end positions [T, 2, 3]: near the floor and nearly still.

    The floor defaults to a low percentile of the lower toe's height, so clips captured a few
    centimetres off y = 0 still work.
    """
    if floor is None:
        floor = float(np.percentile(toe_positions[:, :, 1].min(axis=1), 5))
    vel = np.zeros(toe_positions.shape[:2])
    if len(toe_positions) > 1:
        step = np.linalg.norm(np.diff(toe_positions[:, :, [0, 2]], axis=0), axis=-1) * fps
        # Central speed: mean of the steps into and out of each frame.
        vel[1:-1] = 0.5 * (step[:-1] + step[1:])
        vel[0], vel[-1] = step[0], step[-1]
    near = toe_positions[:, :, 1] < floor + height
    return (near & (vel < speed)).astype(np.float32)


def root_steps(root: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """The root's channels that count per frame [T, 3] (dx, dz in the previous frame's heading frame, dyaw; the
    first frame's 0) from its path [T, 3] and unwrapped heading [T]: what `decode` integrates back."""
    delta = np.zeros((len(root), 3))
    delta[1:] = root[1:] - root[:-1]
    prev_yaw = np.concatenate([yaw[:1], yaw[:-1]])
    local = Rotation.from_euler("y", -prev_yaw[:, None]).apply(delta)
    return np.stack([local[:, 0], local[:, 2], yaw - prev_yaw], axis=-1)


def encode(motion: Motion, floor: float | None = None) -> np.ndarray:
    """Motion -> features [T, D] (float32)."""
    s = motion.skeleton
    layout = FeatureLayout.for_skeleton(s)
    yaw, swing = yaw_and_swing(motion.rotations[:, 0])
    root = motion.root_positions
    t = motion.num_frames
    feats = np.zeros((t, layout.size), dtype=np.float64)

    feats[:, [0, 2, 3]] = root_steps(root, yaw)
    feats[:, 1] = root[:, 1]
    feats[:, 4] = swing[:, 0]
    feats[:, 5] = swing[:, 2]
    feats[:, layout.rotations] = motion.rotations[:, 1:].reshape(t, -1)

    _, _, ends = fk_numpy(s, motion.rotations, root, with_end_sites=True)
    rel = (ends - root[:, None, :]).reshape(-1, 3)
    ends_local = Rotation.from_euler("y", -np.repeat(yaw, len(s.end_sites))[:, None]).apply(rel)
    feats[:, layout.end_effectors] = ends_local.reshape(t, -1)
    feats[:, layout.contacts] = foot_contacts(ends[:, list(TOE_ENDS)], motion.fps, floor)
    return feats.astype(np.float32)


def decode(
    features: np.ndarray,
    fps: float,
    skeleton: Skeleton = DEFAULT_SKELETON,
    start_yaw: float = 0.0,
    start_xz: tuple[float, float] = (0.0, 0.0),
) -> Motion:
    """Features [T, D] -> Motion, integrating the root deltas (float64) from a start heading/position.

    The first frame's deltas are ignored: the clip starts at `start_xz` facing `start_yaw`.
    """
    layout = FeatureLayout.for_skeleton(skeleton)
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != layout.size:
        raise ValueError(f"features must be [T, {layout.size}], got {f.shape}")
    t = len(f)
    dyaw = f[:, 3].copy()
    dyaw[0] = 0.0
    yaw = start_yaw + np.cumsum(dyaw)
    prev_yaw = np.concatenate([[start_yaw], yaw[:-1]])
    local = np.stack([f[:, 0], np.zeros(t), f[:, 2]], axis=-1)
    local[0] = 0.0
    world_delta = Rotation.from_euler("y", prev_yaw[:, None]).apply(local)
    root = np.cumsum(world_delta, axis=0)
    root[:, 0] += start_xz[0]
    root[:, 2] += start_xz[1]
    root[:, 1] = f[:, 1]

    swing = np.stack([f[:, 4], np.zeros(t), f[:, 5]], axis=-1)
    root_rot = (Rotation.from_euler("y", yaw[:, None]) * Rotation.from_rotvec(swing)).as_rotvec()
    rots = np.concatenate([root_rot[:, None], f[:, layout.rotations].reshape(t, -1, 3)], axis=1)
    return Motion(rots, root, fps, skeleton)


def start_pose(motion: Motion) -> tuple[float, tuple[float, float]]:
    """The (start_yaw, start_xz) that `decode` needs to put a clip back where it was."""
    yaw = heading_frames(motion[0:1])[0]
    return float(yaw), (float(motion.root_positions[0, 0]), float(motion.root_positions[0, 2]))


@dataclass
class Normalizer:
    """Per-channel mean/std. Constant channels (e.g. fingers at rest) get std 1, never a divide by 0."""

    mean: np.ndarray
    std: np.ndarray
    constant: np.ndarray  # bool mask of channels that did not vary in the fitted data

    MIN_STD = 1e-4

    @classmethod
    def fit(cls, features: np.ndarray | list[np.ndarray], binary: slice | None = None) -> Normalizer:
        """Statistics over frames; channels in `binary` (contacts) are left as they are (0/1)."""
        x = np.concatenate(features) if isinstance(features, list) else np.asarray(features)
        x = x.astype(np.float64)
        mean = x.mean(axis=0)
        std = x.std(axis=0)
        constant = std < cls.MIN_STD
        std = np.where(constant, 1.0, std)
        if binary is not None:
            mean[binary] = 0.0
            std[binary] = 1.0
        return cls(mean.astype(np.float32), std.astype(np.float32), constant)

    def normalize(self, x: np.ndarray) -> np.ndarray:
        return ((x - self.mean) / self.std).astype(np.float32)

    def denormalize(self, x: np.ndarray) -> np.ndarray:
        return (x * self.std + self.mean).astype(np.float32)

    def save(self, path: str | Path) -> None:
        with atomic_open(path, "wb") as f:
            np.savez(f, mean=self.mean, std=self.std, constant=self.constant)

    @classmethod
    def load(cls, path: str | Path) -> Normalizer:
        z = np.load(path)
        return cls(z["mean"], z["std"], z["constant"])
