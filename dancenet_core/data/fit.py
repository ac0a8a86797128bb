"""Fit the 55-joint skeleton to marker positions (Dance with Melody): positions -> rotations.

Two steps, per sequence:
1. A performer skeleton: our rest offsets rescaled to the data's median bone lengths (left/right
   averaged, so the skeleton stays symmetric and the mirror augmentation stays exact).
2. Rotations: an analytic start (pelvis, thorax and head frames from their markers; limbs by the
   smallest rotation onto each observed bone), then a joint optimisation of all frames in torch:
   marker error + a smoothness term on joint accelerations (non-causal, so no lag) + anatomical
   priors (knees hinge, spine bends evenly). Fingers, jaw and eyes stay at rest.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from ..kinematics import fk_numpy
from ..motion import Motion
from ..nets.kinematics_torch import fk_torch
from ..skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, EndSite, Skeleton
from .dance_with_melody import P

J = JOINT_INDEX


@dataclass(frozen=True)
class Target:
    """A point of our skeleton (joint + offset in its frame) matched to a data point (or mean of two)."""

    name: str
    joint: int
    offset: tuple[float, float, float]
    points: tuple[int, ...]
    weight: float = 1.0
    matched: bool = True  # a joint, counted in the fit error; False for points that only set a turn


def _norm(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _median_len(pos: np.ndarray, a: int, b: int) -> float:
    return float(np.median(np.linalg.norm(pos[:, a] - pos[:, b], axis=-1)))


def _frame(x: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Rotation matrices [T,3,3] whose columns are x (left), y (up, orthogonalised), z = x cross y."""
    x = _norm(x)
    y = _norm(up - (up * x).sum(-1, keepdims=True) * x)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def performer_skeleton(pos: np.ndarray) -> tuple[Skeleton, list[Target]]:
    """Our skeleton sized to this performer's markers, and the marker targets for fitting."""
    off = DEFAULT_SKELETON.offsets.copy()
    mid_hip = 0.5 * (pos[:, P["l_hip"]] + pos[:, P["r_hip"]])
    mid_sh = 0.5 * (pos[:, P["l_shoulder"]] + pos[:, P["r_shoulder"]])
    head_c = 0.5 * (pos[:, P["head_l"]] + pos[:, P["head_r"]])
    pelvis_frame = _frame(pos[:, P["l_hip"]] - pos[:, P["r_hip"]], mid_sh - mid_hip)

    # Hips: the median hip marker in the pelvis frame, left and mirrored right averaged.
    lh = np.einsum("tji,tj->ti", pelvis_frame, pos[:, P["l_hip"]] - pos[:, P["pelvis"]])
    rh = np.einsum("tji,tj->ti", pelvis_frame, pos[:, P["r_hip"]] - pos[:, P["pelvis"]])
    hip = 0.5 * (np.median(lh, 0) + np.median(rh, 0) * [-1, 1, 1])
    off[J["left_hip"]], off[J["right_hip"]] = hip, hip * [-1, 1, 1]

    def set_len(names: tuple[str, str], length: float) -> None:
        for n in names:
            off[J[n]] *= length / np.linalg.norm(off[J[n]])

    thigh = 0.5 * (_median_len(pos, P["l_hip"], P["l_knee"]) + _median_len(pos, P["r_hip"], P["r_knee"]))
    shin = 0.5 * (_median_len(pos, P["l_knee"], P["l_ankle"]) + _median_len(pos, P["r_knee"], P["r_ankle"]))
    upper = 0.5 * (_median_len(pos, P["l_shoulder"], P["l_elbow"])
                   + _median_len(pos, P["r_shoulder"], P["r_elbow"]))  # fmt: skip
    fore = 0.5 * (_median_len(pos, P["l_elbow"], P["l_wrist"]) + _median_len(pos, P["r_elbow"], P["r_wrist"]))
    foot = 0.5 * (_median_len(pos, P["l_ankle"], P["l_toe"]) + _median_len(pos, P["r_ankle"], P["r_toe"]))
    set_len(("left_knee", "right_knee"), thigh)
    set_len(("left_ankle", "right_ankle"), shin)
    set_len(("left_elbow", "right_elbow"), upper)
    set_len(("left_wrist", "right_wrist"), fore)

    # Torso: scale the spine and collar heights to the pelvis-to-shoulder-line distance, and the
    # collar/shoulder widths to the shoulder markers' spacing.
    rest = Skeleton(off).rest_positions()
    rest_mid_sh = 0.5 * (rest[J["left_shoulder"]] + rest[J["right_shoulder"]])
    torso = float(np.median(np.linalg.norm(mid_sh - pos[:, P["pelvis"]], axis=-1)))
    k = torso / np.linalg.norm(rest_mid_sh)
    for n in ("spine1", "spine2", "spine3", "left_collar", "right_collar", "left_shoulder", "right_shoulder"):
        off[J[n], 1:] *= k
    width = _median_len(pos, P["l_shoulder"], P["r_shoulder"])
    kx = 0.5 * width / rest[J["left_shoulder"], 0]
    for n in ("left_collar", "right_collar", "left_shoulder", "right_shoulder"):
        off[J[n], 0] *= kx

    # Head: the midpoint of the two head markers sits on the head's centre line; scale neck and head.
    rest = Skeleton(off).rest_positions()
    rest_mid_sh = 0.5 * (rest[J["left_shoulder"]] + rest[J["right_shoulder"]])
    head_site = np.array([0.0, 0.10, 0.0])
    rest_head = rest[J["head"]] + head_site - rest_mid_sh
    kh = float(np.median(np.linalg.norm(head_c - mid_sh, axis=-1))) / np.linalg.norm(rest_head)
    for n in ("neck", "head"):
        off[J[n]] *= kh
    head_site = head_site * kh
    half_head = 0.5 * _median_len(pos, P["head_l"], P["head_r"])

    # Feet: the toe end sits at the toe marker; scale foot and toe-end offsets together.
    ends = list(DEFAULT_SKELETON.end_sites)
    toe_rest = off[J["left_foot"]] + np.array(ends[0].offset)
    kf = foot / np.linalg.norm(toe_rest)
    for n in ("left_foot", "right_foot"):
        off[J[n]] *= kf
    ends[0] = replace(ends[0], offset=tuple(np.array(ends[0].offset) * kf))
    ends[1] = replace(ends[1], offset=tuple(np.array(ends[1].offset) * kf))
    ends[2] = EndSite("head_end", J["head"], (0.0, float(0.16 * kh), 0.0))
    return Skeleton(off, end_sites=tuple(ends)), _marker_targets(head_site, half_head, ends[0].offset)


def _marker_targets(head_site: np.ndarray, half_head: float, toe: tuple[float, float, float]) -> list[Target]:
    """The markers the fit matches: each joint's own, the head's two (its centre, and each side half a head
    width out, weighted less) and the toes' (at the toe end `toe` from the foot joint)."""
    targets = [
        Target("pelvis", J["pelvis"], (0, 0, 0), (P["pelvis"],)),
        Target("head", J["head"], tuple(head_site), (P["head_l"], P["head_r"])),
        Target("head_l", J["head"], (half_head, *head_site[1:]), (P["head_l"],), 0.3, matched=False),
        Target("head_r", J["head"], (-half_head, *head_site[1:]), (P["head_r"],), 0.3, matched=False),
    ]
    for side, s in (("left", "l"), ("right", "r")):
        targets += [
            Target(f"{side}_hip", J[f"{side}_hip"], (0, 0, 0), (P[f"{s}_hip"],)),
            Target(f"{side}_knee", J[f"{side}_knee"], (0, 0, 0), (P[f"{s}_knee"],)),
            Target(f"{side}_ankle", J[f"{side}_ankle"], (0, 0, 0), (P[f"{s}_ankle"],)),
            Target(f"{side}_toe", J[f"{side}_foot"], toe, (P[f"{s}_toe"],)),
            Target(f"{side}_shoulder", J[f"{side}_shoulder"], (0, 0, 0), (P[f"{s}_shoulder"],)),
            Target(f"{side}_elbow", J[f"{side}_elbow"], (0, 0, 0), (P[f"{s}_elbow"],)),
            Target(f"{side}_wrist", J[f"{side}_wrist"], (0, 0, 0), (P[f"{s}_wrist"],)),
        ]
    return targets


def target_positions(pos: np.ndarray, targets: list[Target]) -> np.ndarray:
    """The data side of each target, [T, K, 3]."""
    return np.stack([pos[:, list(t.points)].mean(axis=1) for t in targets], axis=1)


def model_positions(skeleton: Skeleton, rotations: np.ndarray, root: np.ndarray,
                    targets: list[Target]) -> np.ndarray:
    """Our side of each target after FK, [T, K, 3]."""
    wp, wr = fk_numpy(skeleton, rotations, root)
    return np.stack([wp[:, t.joint] + wr[:, t.joint] @ np.array(t.offset) for t in targets], axis=1)


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (rotation vectors [T,3]) turning direction a [3] onto directions b [T,3]."""
    a = _norm(np.broadcast_to(a, b.shape))
    b = _norm(b)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1, keepdims=True)
    c = (a * b).sum(-1, keepdims=True)
    return _norm(axis) * np.arctan2(s, c)


def initial_pose(skeleton: Skeleton, pos: np.ndarray) -> np.ndarray:
    """Analytic start for the optimiser: local rotation vectors [T, 55, 3]."""
    n = len(pos)
    rot = np.zeros((n, skeleton.num_joints, 3))
    off = skeleton.offsets
    mid_hip = 0.5 * (pos[:, P["l_hip"]] + pos[:, P["r_hip"]])
    mid_sh = 0.5 * (pos[:, P["l_shoulder"]] + pos[:, P["r_shoulder"]])
    head_c = 0.5 * (pos[:, P["head_l"]] + pos[:, P["head_r"]])
    r_pelvis = _frame(pos[:, P["l_hip"]] - pos[:, P["r_hip"]], mid_sh - mid_hip)
    r_thorax = _frame(pos[:, P["l_shoulder"]] - pos[:, P["r_shoulder"]], mid_sh - mid_hip)
    r_head = _frame(pos[:, P["head_l"]] - pos[:, P["head_r"]], head_c - mid_sh)
    rot[:, 0] = Rotation.from_matrix(r_pelvis).as_rotvec()
    bend = Rotation.from_matrix(np.einsum("tji,tjk->tik", r_pelvis, r_thorax)).as_rotvec() / 3.0
    for name in ("spine1", "spine2", "spine3"):
        rot[:, J[name]] = bend
    nod = Rotation.from_matrix(np.einsum("tji,tjk->tik", r_thorax, r_head)).as_rotvec() / 2.0
    rot[:, J["neck"]] = rot[:, J["head"]] = nod

    chains = []
    for side, s in (("left", "l"), ("right", "r")):
        chains += [
            (f"{side}_hip", f"{side}_knee", P[f"{s}_knee"], P[f"{s}_hip"]),
            (f"{side}_knee", f"{side}_ankle", P[f"{s}_ankle"], P[f"{s}_knee"]),
            (f"{side}_ankle", f"{side}_foot", P[f"{s}_toe"], P[f"{s}_ankle"]),
            (f"{side}_shoulder", f"{side}_elbow", P[f"{s}_elbow"], P[f"{s}_shoulder"]),
            (f"{side}_elbow", f"{side}_wrist", P[f"{s}_wrist"], P[f"{s}_elbow"]),
        ]
    for joint, child, tip, base in chains:
        _, wr = fk_numpy(skeleton, rot, np.zeros((n, 3)))
        parent_r = wr[:, skeleton.parents[J[joint]]]
        observed = np.einsum("tji,tj->ti", parent_r, pos[:, tip] - pos[:, base])
        rest_dir = off[J[child]]
        if child.endswith("foot"):
            rest_dir = off[J[child]] + np.array(skeleton.end_sites[0].offset)
        rot[:, J[joint]] = _swing(rest_dir, observed)
    return rot


def fit_sequence(
    pos: np.ndarray,
    fps: float,
    steps: int = 200,
    smooth_weight: float = 0.5,
    progress: bool = False,
) -> tuple[Motion, list[Target]]:
    """Fit our skeleton to marker positions [T, 23, 3]; returns the motion and the targets used."""
    skeleton, targets = performer_skeleton(pos)
    # Joints no marker constrains (their twist would wander): the ball of the foot and the wrists.
    frozen = [J["left_foot"], J["right_foot"], J["left_wrist"], J["right_wrist"]]
    motion = optimise_rotations(skeleton, targets, target_positions(pos, targets), initial_pose(skeleton, pos),
                                pos[:, P["pelvis"]], fps, frozen, steps, smooth_weight, progress)
    return motion, targets


def optimise_rotations(
    skeleton: Skeleton,
    targets: list[Target],
    want: np.ndarray,
    rot0: np.ndarray,
    root0: np.ndarray,
    fps: float,
    frozen: list[int],
    steps: int = 200,
    smooth_weight: float = 0.5,
    progress: bool = False,
) -> Motion:
    """Body rotations and root path that put the targets on `want` [T, K, 3], from the start `rot0` [T, 55, 3].

    All frames at once: target error + joint accelerations (non-causal, so no lag) + anatomical priors.
    `frozen` joints keep their start rotation; joints past the body (fingers, jaw, eyes) keep theirs too.
    """
    body = Skeleton(skeleton.offsets[:BODY_JOINTS], skeleton.names[:BODY_JOINTS],
                    skeleton.parents[:BODY_JOINTS], ())
    dtype = torch.float32  # metres: float32 is ample, and twice as fast as float64
    want_t = torch.tensor(want, dtype=dtype)
    weights = torch.tensor([t.weight for t in targets], dtype=dtype)
    t_joint = torch.tensor([t.joint for t in targets])
    t_off = torch.tensor([t.offset for t in targets], dtype=dtype)
    rot = torch.tensor(rot0[:, :BODY_JOINTS], dtype=dtype, requires_grad=True)
    root = torch.tensor(root0, dtype=dtype, requires_grad=True)
    opt = torch.optim.Adam([rot, root], lr=0.01)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)
    dt2 = (1.0 / fps) ** 2
    spine = [J["spine1"], J["spine2"], J["spine3"]]
    knees = [J["left_knee"], J["right_knee"]]
    elbows = [J["left_elbow"], J["right_elbow"]]
    for step in range(steps):
        opt.zero_grad()
        wp, wr, _ = fk_torch(body, rot, root)
        got = wp[:, t_joint] + (wr[:, t_joint] @ t_off.unsqueeze(-1)).squeeze(-1)
        err = ((got - want_t) ** 2).sum(-1)
        loss = (err * weights).mean() / weights.mean()
        acc = (wp[2:] - 2 * wp[1:-1] + wp[:-2]) / dt2  # m/s^2
        loss = loss + smooth_weight * 1e-6 * (acc**2).sum(-1).mean()
        # Knees hinge about their local x axis, elbows about y; the three spine joints share the bend;
        # joint rotations change smoothly (this fixes twists the targets leave open).
        loss = loss + 1e-3 * (rot[:, knees, 1:] ** 2).sum(-1).mean()
        loss = loss + 1e-3 * (rot[:, elbows][..., [0, 2]] ** 2).sum(-1).mean()
        loss = loss + 1e-3 * ((rot[1:, 1:] - rot[:-1, 1:]) ** 2).sum(-1).mean()
        loss = loss + 1e-3 * ((rot[:, spine] - rot[:, spine].mean(1, keepdim=True)) ** 2).sum(-1).mean()
        loss.backward()
        rot.grad[:, frozen] = 0.0  # Adam leaves a parameter whose gradient is always zero where it started
        opt.step()
        sched.step()
        if progress and step % 50 == 0:
            print(f"  step {step}: rms {err.mean().sqrt().item() * 100:.2f} cm")
    rotations = rot0.copy()
    rotations[:, :BODY_JOINTS] = rot.detach().numpy()
    return Motion(rotations, root.detach().numpy(), fps, skeleton)


# Each joint target's parent along the body's chains, for the stretch analysis.
_CHAIN_PARENT = {"head": "pelvis"} | {
    f"{side}_{child}": ("pelvis" if parent == "pelvis" else f"{side}_{parent}")
    for side in ("left", "right")
    for child, parent in (("hip", "pelvis"), ("knee", "hip"), ("ankle", "knee"), ("toe", "ankle"),
                          ("shoulder", "pelvis"), ("elbow", "shoulder"), ("wrist", "elbow"))
}


def joint_columns(targets: list[Target]) -> list[int]:
    """The matched joints' columns: points that only set a turn (the head markers) are not joints."""
    return [k for k, t in enumerate(targets) if t.matched]


def fit_errors(motion: Motion, pos: np.ndarray, targets: list[Target]) -> np.ndarray:
    """Per-frame distances (metres) between our fitted joints and the data's, [T, K] (matched joints)."""
    got = model_positions(motion.skeleton, motion.rotations, motion.root_positions, targets)
    cols = joint_columns(targets)
    return np.linalg.norm(got - target_positions(pos, targets), axis=-1)[:, cols]


def stretch_errors(motion: Motion, pos: np.ndarray, targets: list[Target], along_chain: bool = True
                   ) -> np.ndarray:
    """Marker stretch that a rigid skeleton cannot follow, [T, K] (matched joints): the difference between
    the markers' distance and our constant bone length, frame by frame, for each joint's own bone and,
    with `along_chain`, summed over the bones from the pelvis (an upper bound of its effect).
    """
    got = model_positions(motion.skeleton, motion.rotations, motion.root_positions, targets)
    want = target_positions(pos, targets)
    idx = {t.name: k for k, t in enumerate(targets)}
    out = np.zeros((len(pos), len(targets)))
    for t in targets:
        name, acc = t.name, np.zeros(len(pos))
        while name in _CHAIN_PARENT:
            a, b = idx[name], idx[_CHAIN_PARENT[name]]
            acc += np.abs(np.linalg.norm(want[:, a] - want[:, b], axis=-1)
                          - np.linalg.norm(got[:, a] - got[:, b], axis=-1))
            name = _CHAIN_PARENT[name] if along_chain else ""
        out[:, idx[t.name]] = acc
    return out[:, joint_columns(targets)]
