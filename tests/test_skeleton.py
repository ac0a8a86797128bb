"""The 55-joint skeleton and forward kinematics, checked against poses computed by hand."""

from __future__ import annotations

import numpy as np
import torch

from dancenet_core.kinematics import fk_numpy
from dancenet_core.nets.kinematics_torch import fk_torch
from dancenet_core.skeleton import (
    DEFAULT_SKELETON,
    END_EFFECTORS,
    JOINT_INDEX,
    JOINT_NAMES,
    MIRROR_INDEX,
    PARENTS,
    Skeleton,
)


def test_layout_is_smplx() -> None:
    assert len(JOINT_NAMES) == 55
    assert len(PARENTS) == 55
    assert JOINT_NAMES[:3] == ("pelvis", "left_hip", "right_hip")
    assert JOINT_NAMES[22:25] == ("jaw", "left_eye_smplhf", "right_eye_smplhf")
    assert PARENTS[JOINT_INDEX["left_index1"]] == JOINT_INDEX["left_wrist"]
    assert PARENTS[JOINT_INDEX["right_thumb3"]] == JOINT_INDEX["right_thumb2"]
    assert [e.name for e in END_EFFECTORS] == ["left_toe_end", "right_toe_end", "head_end", "left_hand",
                                               "right_hand"]


def test_rest_pose_is_a_plausible_symmetric_human() -> None:
    rest = DEFAULT_SKELETON.rest_positions()
    # Left side is +X, and every left joint mirrors its right partner.
    assert rest[JOINT_INDEX["left_wrist"], 0] > 0.5
    np.testing.assert_allclose(rest[list(MIRROR_INDEX)] * [-1, 1, 1], rest, atol=1e-12)
    height = DEFAULT_SKELETON.rest_pelvis_height() + rest[JOINT_INDEX["head"], 1] + 0.16
    assert 1.6 < height < 1.8


def test_fk_hand_computed_chain() -> None:
    """Three joints in a line along +X; bend the middle one 90 degrees about +Z."""
    sk = Skeleton(np.array([[0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]]), ("a", "b", "c"), (-1, 0, 1), ())
    rot = np.zeros((1, 3, 3))
    rot[0, 1] = [0, 0, np.pi / 2]
    pos, _ = fk_numpy(sk, rot, np.array([[0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(pos[0], [[0, 1, 0], [1, 1, 0], [1, 3, 0]], atol=1e-12)
    # Root yaw of 90 degrees about +Y turns +X into -Z.
    rot = np.zeros((1, 3, 3))
    rot[0, 0] = [0, np.pi / 2, 0]
    pos, _ = fk_numpy(sk, rot, np.zeros((1, 3)))
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 0, -1], [0, 0, -3]], atol=1e-12)


def test_fk_elbow_bend_on_the_55_joint_skeleton() -> None:
    """Left elbow bent 90 degrees about +Y: the wrist moves from +X to -Z of the elbow."""
    rot = np.zeros((1, 55, 3))
    rot[0, JOINT_INDEX["left_elbow"]] = [0, np.pi / 2, 0]
    pos, _, ends = fk_numpy(DEFAULT_SKELETON, rot, np.zeros((1, 3)), with_end_sites=True)
    elbow, wrist = pos[0, JOINT_INDEX["left_elbow"]], pos[0, JOINT_INDEX["left_wrist"]]
    np.testing.assert_allclose(wrist - elbow, [0, 0, -0.25], atol=1e-12)
    np.testing.assert_allclose(ends[0, 3] - wrist, [0, 0, -0.08], atol=1e-12)


def test_torch_fk_matches_numpy_and_is_differentiable() -> None:
    rng = np.random.default_rng(1)
    rot = rng.normal(0, 0.6, (4, 7, 55, 3))
    rot[0, 0, 5] = 0.0  # exercise the zero-angle branch
    root = rng.normal(0, 1, (4, 7, 3))
    p_np, r_np, e_np = fk_numpy(DEFAULT_SKELETON, rot, root, with_end_sites=True)
    rot_t = torch.tensor(rot, requires_grad=True)
    p_t, r_t, e_t = fk_torch(DEFAULT_SKELETON, rot_t, torch.tensor(root))
    np.testing.assert_allclose(p_t.detach().numpy(), p_np, atol=1e-10)
    np.testing.assert_allclose(r_t.detach().numpy(), r_np, atol=1e-10)
    np.testing.assert_allclose(e_t.detach().numpy(), e_np, atol=1e-10)
    e_t.sum().backward()
    assert rot_t.grad is not None
    assert torch.isfinite(rot_t.grad).all()
    assert rot_t.grad.abs().sum() > 0
