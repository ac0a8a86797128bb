"""Continue a dance from a frame: the kept frames stay as they were and the new ones are laid on after
them, so the join neither jumps nor snaps.

The model hears the kept frames as its own (see `model.sampler.CachedSampler.run`'s `prefix`), yet its
first new frame is a fresh draw from the mixture, and the kept frames went through the foot clean-up and
smoothing it never saw: a joint can change speed at the join more than it ever does while dancing. The
new frames therefore take an offset that makes the first of them continue the kept motion at its own
velocity and fades out (a cubic Hermite curve: no kink where it starts or ends) over `BLEND_S`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .motion import Motion
from .representation import decode, start_pose
from .skeleton import Skeleton

BLEND_S = 0.4  # how long the join's offset takes to fade (a beat at 150 BPM)


def _hermite(frames: int, offset: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """[frames, ...] from `offset` (at frame 0) with slope `velocity` per frame, easing to 0 and flat at the end."""
    s = (np.arange(frames) / frames).reshape(-1, *([1] * offset.ndim))
    return (2 * s**3 - 3 * s**2 + 1) * offset + (s**3 - 2 * s**2 + s) * frames * velocity


def join_kept(kept: Motion, feats: np.ndarray, k: int, skeleton: Skeleton) -> Motion:
    """Kept frames before `k` unchanged, then the new ones (features from frame k - 1 on, decoded from where
    kept frame k - 1 stands, its place and heading), offset so the first continues the kept motion."""
    new = decode(feats[k - 1 :], kept.fps, skeleton, *start_pose(kept[k - 1 : k]))[1:]
    n = min(new.num_frames, max(2, int(round(BLEND_S * kept.fps))))
    rot, root = new.rotations.copy(), new.root_positions.copy()
    last, before = Rotation.from_rotvec(kept.rotations[k - 1]), Rotation.from_rotvec(kept.rotations[k - 2])
    first, second = Rotation.from_rotvec(rot[0]), Rotation.from_rotvec(rot[1])
    # Where the kept motion would be one frame on at its own angular velocity, and what the new frames need
    # to get there (offsets applied on the left, as rotation vectors: small at a join).
    expected = last * (before.inv() * last)
    offset = (expected * first.inv()).as_rotvec()
    velocity = (before.inv() * last).as_rotvec() - (first.inv() * second).as_rotvec()
    fade = _hermite(n, offset, velocity)  # [n, J, 3]
    rot[:n] = (Rotation.from_rotvec(fade.reshape(-1, 3)) * Rotation.from_rotvec(rot[:n].reshape(-1, 3))) \
        .as_rotvec().reshape(n, -1, 3)
    kept_step = kept.root_positions[k - 1] - kept.root_positions[k - 2]
    root_offset = kept.root_positions[k - 1] + kept_step - root[0]
    root[:n] += _hermite(n, root_offset, kept_step - (root[1] - root[0]))
    return Motion(np.concatenate([kept.rotations[:k], rot]), np.concatenate([kept.root_positions[:k], root]),
                  kept.fps, skeleton)


def keep_original(kept: Motion, dance: Motion, join_s: float) -> Motion:
    """`dance` at `kept`'s frame rate, with `kept`'s own frames (not resampled ones) before `join_s`."""
    out = dance.resampled(kept.fps)
    j = min(int(np.ceil(join_s * kept.fps - 1e-6)), out.num_frames, kept.num_frames)
    return Motion(np.concatenate([kept.rotations[:j], out.rotations[j:]]),
                  np.concatenate([kept.root_positions[:j], out.root_positions[j:]]), kept.fps, out.skeleton)
