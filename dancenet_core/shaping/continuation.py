"""Continue a dance from a frame: the kept frames stay as they were and the new ones are laid on after
them, so the join neither jumps nor snaps.

The model hears the kept frames as its own (see `runtime.sampler.CachedSampler.run`'s `prefix`), and the foot
clean-up and smoothing run over kept and new frames together, so the new dance, decoded with the kept frames
before it, already flows through the join; only its version of the kept frames differs a little from the kept
frames themselves (cleaned twice, smoothed with new frames beside them). The new frames take that difference,
its value, slope and curvature at the last kept frame, as an offset that fades to nothing over `BLEND_S` (a
quintic: no jump in place, speed or acceleration at either end), as game engines blend between animations
("inertialization"). Taking the kept motion's own velocity against the first new frames' instead put the join
at the default temperature above the dance's own 95th percentile of acceleration (0.063 against 0.056).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..motion import Motion
from ..representation import decode, start_pose
from ..skeleton import Skeleton

BLEND_S = 0.4  # how long the join's offset takes to fade (a beat at 150 BPM)
DIFFERENCES = 3  # kept frames compared with the new dance's: the offset's value, slope and curvature


def _fade(frames: int, history: np.ndarray) -> np.ndarray:
    """Offsets [frames, ...] for the frames after `history`'s last [H, ...] (H = 2 or 3): starting with its
    value, slope and (H = 3) curvature per frame, and reaching 0 with no slope or curvature at `frames`."""
    x0, v0 = history[-1], history[-1] - history[-2]
    a0 = history[-1] - 2 * history[-2] + history[-3] if len(history) > 2 else np.zeros_like(x0)
    n = float(frames)
    t = np.arange(1, frames + 1, dtype=float).reshape(-1, *([1] * x0.ndim))
    c3 = -(20 * x0 + 12 * v0 * n + 3 * a0 * n**2) / (2 * n**3)
    c4 = (30 * x0 + 16 * v0 * n + 3 * a0 * n**2) / (2 * n**4)
    c5 = -(12 * x0 + 6 * v0 * n + a0 * n**2) / (2 * n**5)
    return x0 + v0 * t + a0 / 2 * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5


def join_kept(kept: Motion, feats: np.ndarray, k: int, skeleton: Skeleton) -> Motion:
    """Kept frames before `k` unchanged, then the new ones (the dance's features [T, D], kept frames included,
    decoded from where kept frame k - 3 stands), offset by the kept frames' difference from the new dance."""
    h = min(k, DIFFERENCES)
    return splice(kept, decode(feats[k - h :], kept.fps, skeleton, *start_pose(kept[k - h : k - h + 1])), k, h)


def splice(kept: Motion, new: Motion, k: int, h: int) -> Motion:
    """`kept`'s frames before `k` unchanged, then `new`'s after its first `h` (which stand for kept frames
    k - h .. k - 1), offset by how far those h frames are from the kept ones, the offset fading out."""
    rot, root = new.rotations[h:].copy(), new.root_positions[h:].copy()
    # How far the kept frames are from the new dance's version of them (rotations as left offsets, rotation
    # vectors: small here), faded out over the first new frames.
    rot_diff = (Rotation.from_rotvec(kept.rotations[k - h : k].reshape(-1, 3))
                * Rotation.from_rotvec(new.rotations[:h].reshape(-1, 3)).inv()).as_rotvec().reshape(h, -1, 3)
    n = min(len(rot), max(2, int(round(BLEND_S * kept.fps))))
    offsets = Rotation.from_rotvec(_fade(n, rot_diff).reshape(-1, 3))
    rot[:n] = (offsets * Rotation.from_rotvec(rot[:n].reshape(-1, 3))).as_rotvec().reshape(n, -1, 3)
    root[:n] += _fade(n, kept.root_positions[k - h : k] - new.root_positions[:h])
    return Motion(np.concatenate([kept.rotations[:k], rot]), np.concatenate([kept.root_positions[:k], root]),
                  kept.fps, new.skeleton)


def keep_original(kept: Motion, dance: Motion, join_s: float) -> Motion:
    """`dance` at `kept`'s frame rate, with `kept`'s own frames (not resampled ones) before `join_s`."""
    out = dance.resampled(kept.fps)
    j = min(int(np.ceil(join_s * kept.fps - 1e-6)), out.num_frames, kept.num_frames)
    return Motion(np.concatenate([kept.rotations[:j], out.rotations[j:]]),
                  np.concatenate([kept.root_positions[:j], out.root_positions[j:]]), kept.fps, out.skeleton)
