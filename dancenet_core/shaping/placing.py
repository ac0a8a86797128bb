"""A dance's frames read between frames, and turned and moved on the floor: what the repeats of a song's sections
(`repeats.py`) and the library's cuts (`library/transitions.py`) both do to lay one dance where another stands."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def sample_frames(rotations: np.ndarray, root_positions: np.ndarray, frames: np.ndarray,
                  first: np.ndarray | int = 0, last: np.ndarray | int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rotations [N, J, 3] and root positions [N, 3] at fractional `frames` of frames [first, last] (numbers, or
    per frame: each frame's clip). Between the two frames around each, quaternions are interpolated normalised-
    linearly the short way round (between neighbouring frames slerp to within 1e-4 rad at a quarter the cost) and
    the root linearly; a frame before `first` or after `last` carries the nearest step on (clamp `frames` to hold
    the end frames instead)."""
    last = len(rotations) - 1 if last is None else last
    lo = np.clip(np.floor(frames).astype(np.int64), first, np.maximum(first, np.asarray(last) - 1))
    hi = np.minimum(lo + 1, last)
    w = (frames - lo)[:, None]
    nj = rotations.shape[1]
    q0, q1 = (Rotation.from_rotvec(rotations[i].reshape(-1, 3)).as_quat().reshape(-1, nj, 4) for i in (lo, hi))
    rots = mixed(q0, np.where((q0 * q1).sum(-1, keepdims=True) < 0, -q1, q1), w)
    return rots, root_positions[lo] * (1 - w) + root_positions[hi] * w


def mixed(q0: np.ndarray, q1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotation vectors [N, J, 3] of the normalised weighted sums of quaternions [N, J, 4] at weights [N, 1]."""
    q = q0 * (1 - w[:, :, None]) + q1 * w[:, :, None]
    return Rotation.from_quat(q.reshape(-1, 4)).as_rotvec().reshape(q0.shape[0], -1, 3)


def turned(rotations: np.ndarray, root_positions: np.ndarray, yaw: float,
           shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames (rotations [N, J, 3], root positions [N, 3]) turned by `yaw` about +Y through the origin and moved by
    `shift` ([x, z]) on the floor: the root's rotation and place change, the pose and the height do not."""
    turn = Rotation.from_euler("y", yaw)
    rots = rotations.copy()
    rots[:, 0] = (turn * Rotation.from_rotvec(rots[:, 0])).as_rotvec()
    return rots, turn.apply(root_positions) + np.array([shift[0], 0.0, shift[1]])
