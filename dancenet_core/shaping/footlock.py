"""The foot clean-up that keeps the pose: each foot held where it stands while the model says it is planted, or
while it stands still on the floor, the leg reaching it by two-bone IK (hip and knee), the foot's own turn and
everything above the hips untouched.

Why: the Foot Constraint Model (a network over the lower body) pins the feet by bending the legs away from the
dancers' (FID_k 44.7 without it, 64.8 with it on the test split). A planted foot only needs its leg to reach
one point on the floor: the hip and knee turn so the ankle lands where it must, the ankle's world turn is kept
(so the foot lies as it did), and the body's path, height and upper body are the network's.

Torch-free: generation runs it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..kinematics import fk_numpy
from ..motion import Motion
from ..skeleton import BODY_JOINTS, JOINT_INDEX
from .floor import toe_ends

LEGS = (("left_hip", "left_knee", "left_ankle"), ("right_hip", "right_knee", "right_ankle"))
BLEND_S = 0.12  # a hold eases in and out over at least this long (3 frames at 25 fps), so a foot never jumps
EASE_SPEED = 0.5  # m/s: easing a hold in or out adds at most about this much to the foot's speed
GAP_S = 1.0  # between two holds of one foot at most this far apart the shift goes straight from one to the other
# A toe end this near the floor (the contact height of the sliding measure and of the training contacts)...
GROUND_M = 0.05
# ...and slower than this over it stands, whatever the model predicted. Chosen with GROUND_M on the validation
# songs (docs/training.md): 2 cm and 0.5 m/s held too few of the feet that slide (sliding 0.47 against the
# dancers' 0.57); 5 cm and 0.65 m/s, 0.36 at no cost in FID_k; 1 m/s, 0.24 but FID_g and style consistency worse.
STILL_MPS = 0.65
MIN_RUN_S = 0.08  # a predicted contact shorter than this (one frame at 25 fps) is the model's flicker, not a step


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation matrices [N, 3, 3] of the smallest turns taking directions a [N, 3] onto b [N, 3]."""
    a, b = _unit(a), _unit(b)
    axis = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(axis, axis=-1), (a * b).sum(-1))
    return Rotation.from_rotvec(_unit(axis) * angle[:, None]).as_matrix()


def contact_runs(planted: np.ndarray, fps: float) -> list[tuple[int, int]]:
    """The runs [start, end) of one foot's contact flags [T] (bool), those shorter than MIN_RUN_S left out."""
    flags = np.r_[False, np.asarray(planted, bool), False]
    starts, ends = np.flatnonzero(~flags[:-1] & flags[1:]), np.flatnonzero(flags[:-1] & ~flags[1:])
    shortest = max(1, int(round(MIN_RUN_S * fps)))
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True) if b - a >= shortest]


def _ease(x: np.ndarray) -> np.ndarray:
    """0 -> 1 with no slope at either end (smoothstep)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def hold_offsets(toe_xz: np.ndarray, planted: np.ndarray, fps: float) -> np.ndarray:
    """Where one toe end must move on the floor [T, 2] (x, z) to stand still through each contact run of `planted`
    [T] at the run's mean place, `toe_xz` [T, 2] being where it is.

    Between two runs the offset goes smoothly from the one run's last to the next run's first, so a swinging foot
    keeps its own swing plus a slowly changing shift; before the first run and after the last, and across a gap
    longer than GAP_S, it eases from or to nothing over at least BLEND_S, longer for a larger offset (at most
    EASE_SPEED m/s more foot speed). Why not a short fade at both ends of every run: the body drifts from a planted
    foot by up to 20 cm within a step, and taking that back in a few frames flicks the foot (jitter, fast ankles).
    """
    t = len(toe_xz)
    out = np.zeros((t, 2))
    runs = contact_runs(planted, fps)
    if not runs:
        return out
    ends = []
    for a, b in runs:
        out[a:b] = toe_xz[a:b].mean(0) - toe_xz[a:b]
        ends.append((out[a], out[b - 1]))
    frames = np.arange(t)
    min_ease = max(1, int(round(BLEND_S * fps)))

    def ease_len(offset: np.ndarray) -> int:
        return max(min_ease, int(np.ceil(np.linalg.norm(offset) / EASE_SPEED * fps)))

    first_a, last_b = runs[0][0], runs[-1][1]
    n = ease_len(ends[0][0])  # before the first run: from nothing to its first offset
    before = frames[:first_a]
    out[before] = ends[0][0] * _ease(1 - (first_a - before) / (n + 1))[:, None]
    n = ease_len(ends[-1][1])  # after the last run: back to nothing
    after = frames[last_b:]
    out[after] = ends[-1][1] * _ease(1 - (after - (last_b - 1)) / (n + 1))[:, None]
    for k in range(len(runs) - 1):
        e, s = runs[k][1] - 1, runs[k + 1][0]  # last frame of one run, first of the next
        gap = frames[e + 1 : s]
        if len(gap) == 0:
            continue
        c_e, c_s = ends[k][1], ends[k + 1][0]
        if (s - e) / fps <= GAP_S:
            out[gap] = c_e + (c_s - c_e) * _ease((gap - e) / (s - e))[:, None]
        else:  # a long swing: let go of the one hold and take up the next, each eased
            out[gap] = (c_e * _ease(1 - (gap - e) / (ease_len(c_e) + 1))[:, None]
                        + c_s * _ease(1 - (s - gap) / (ease_len(c_s) + 1))[:, None])
    return out


def planted_feet(motion: Motion, contacts: np.ndarray) -> np.ndarray:
    """Which foot stands on each frame [T, 2] (bool; left, right): where the model predicts a contact, and where a toe
    end it did not plant is on the floor (within GROUND_M of it) and barely moving (under STILL_MPS): a foot left
    standing still on the floor slides as much as a planted one when the body moves on."""
    toes = toe_ends(motion)
    step = np.linalg.norm(np.diff(toes[:, :, [0, 2]], axis=0), axis=-1) * motion.fps
    speed = np.concatenate([step[:1], step]) if len(step) else np.zeros(toes.shape[:2])  # frame 0 as frame 1
    return (np.asarray(contacts) > 0.5) | ((toes[:, :, 1] < GROUND_M) & (speed < STILL_MPS))


def lock_feet(motion: Motion, contacts: np.ndarray) -> Motion:
    """`motion` with each foot held on the floor plane where it stands through each of its predicted contact runs
    (`contacts` [T, 2], left then right toe): the toe end keeps its height and goes to the run's mean place on the
    floor; the legs reach it by two-bone IK. Where the leg cannot reach, it stretches as far as it can."""
    s = motion.skeleton
    rot = motion.rotations.copy()
    wp, wr, toes = fk_numpy(s.feet(), rot[:, :BODY_JOINTS], motion.root_positions, with_end_sites=True)
    for side, (hip, knee, ankle) in enumerate(LEGS):
        shift = hold_offsets(toes[:, side][:, [0, 2]], np.asarray(contacts)[:, side] > 0.5, motion.fps)
        frames = np.flatnonzero(np.abs(shift).max(axis=1) > 1e-9)
        if len(frames) == 0:
            continue
        delta = np.zeros((len(frames), 3))
        delta[:, [0, 2]] = shift[frames]
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
