"""The foot clean-up that keeps the pose: each foot held where it stands while the model says it is planted, the
leg reaching it by two-bone IK (hip and knee), the foot's own turn and everything above the hips untouched.

Why: the Foot Constraint Model (a network over the lower body) pins the feet by bending the legs away from the
dancers' (FID_k 44.7 without it, 64.8 with it on the test split). A planted foot only needs its leg to reach
one point on the floor: the hip and knee turn so the ankle lands where it must, the ankle's world turn is kept
(so the foot lies as it did), and the body's path, height and upper body are the network's.

Torch-free: generation runs it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .kinematics import fk_numpy
from .motion import Motion
from .skeleton import JOINT_INDEX, TOE_ENDS

LEGS = (("left_hip", "left_knee", "left_ankle"), ("right_hip", "right_knee", "right_ankle"))
BLEND_S = 0.12  # the hold eases in and out over this long (3 frames at 25 fps), so a foot never jumps
MIN_RUN_S = 0.08  # a predicted contact shorter than this (one frame at 25 fps) is the model's flicker, not a step


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation matrices [N, 3, 3] of the smallest turns taking directions a [N, 3] onto b [N, 3]."""
    a, b = _unit(a), _unit(b)
    axis = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(axis, axis=-1), (a * b).sum(-1))
    return Rotation.from_rotvec(_unit(axis) * angle[:, None]).as_matrix()


def hold_weights(planted: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """For one foot's contact flags [T] (bool): how much of the hold applies on each frame [T] (1 inside a planted
    run, easing to 0 over BLEND_S either side) and which run it belongs to [T] (-1: none)."""
    t = len(planted)
    flags = np.r_[False, np.asarray(planted, bool), False]
    starts, ends = np.flatnonzero(~flags[:-1] & flags[1:]), np.flatnonzero(flags[:-1] & ~flags[1:])
    keep = (ends - starts) >= max(1, int(round(MIN_RUN_S * fps)))
    starts, ends = starts[keep], ends[keep]
    blend = max(1, int(round(BLEND_S * fps)))
    weight, run = np.zeros(t), np.full(t, -1)
    frames = np.arange(t)
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        outside = np.maximum(a - frames, frames - (b - 1))  # frames before or after the run, 0 inside
        w = np.clip(1.0 - outside / (blend + 1), 0.0, 1.0)
        better = w > weight
        weight[better], run[better] = w[better], k
    return weight, run


def lock_feet(motion: Motion, contacts: np.ndarray) -> Motion:
    """`motion` with each foot held on the floor plane where it stands through each of its predicted contact runs
    (`contacts` [T, 2], left then right toe): the toe end keeps its height and goes to the run's mean place on the
    floor; the legs reach it by two-bone IK. Where the leg cannot reach, it stretches as far as it can."""
    s = motion.skeleton
    rot = motion.rotations.copy()
    wp, wr, ends = fk_numpy(s, rot, motion.root_positions, with_end_sites=True)
    toes = ends[:, list(TOE_ENDS)]
    for side, (hip, knee, ankle) in enumerate(LEGS):
        weight, run = hold_weights(np.asarray(contacts)[:, side] > 0.5, motion.fps)
        frames = np.flatnonzero(weight > 0)
        if len(frames) == 0:
            continue
        toe = toes[:, side]
        anchors = np.array([toe[(run == k) & (weight >= 1)][:, [0, 2]].mean(0)
                            for k in range(run.max() + 1)])
        delta = np.zeros((len(frames), 3))
        delta[:, [0, 2]] = weight[frames, None] * (anchors[run[frames]] - toe[frames][:, [0, 2]])
        h, k, a = (JOINT_INDEX[n] for n in (hip, knee, ankle))
        hp, kp, ap = wp[frames, h], wp[frames, k], wp[frames, a]
        thigh, shin = np.linalg.norm(s.offsets[k]), np.linalg.norm(s.offsets[a])
        target = ap + delta
        reach = target - hp
        d = np.clip(np.linalg.norm(reach, axis=-1), abs(thigh - shin) + 1e-4, (thigh + shin) * (1 - 1e-4))
        u = _unit(reach)
        bend = (kp - hp) - ((kp - hp) * u).sum(-1, keepdims=True) * u  # keeps the knee's side of the leg
        v = _unit(bend)
        cos = np.clip((thigh**2 + d**2 - shin**2) / (2 * thigh * d), -1.0, 1.0)
        knee_new = hp + thigh * (cos[:, None] * u + np.sqrt(1 - cos**2)[:, None] * v)
        r1 = _swing(kp - hp, knee_new - hp)
        ankle_turned = knee_new + np.einsum("nij,nj->ni", r1, ap - kp)
        r2 = _swing(ankle_turned - knee_new, hp + d[:, None] * u - knee_new)
        w_hip = r1 @ wr[frames, h]
        w_knee = r2 @ r1 @ wr[frames, k]
        parent = wr[frames, s.parents[h]]
        local = {h: np.swapaxes(parent, -1, -2) @ w_hip, k: np.swapaxes(w_hip, -1, -2) @ w_knee,
                 a: np.swapaxes(w_knee, -1, -2) @ wr[frames, a]}
        for j, m in local.items():
            rot[frames, j] = Rotation.from_matrix(m).as_rotvec()
    return Motion(rot, motion.root_positions.copy(), motion.fps, s)
