"""Forward kinematics in numpy (scipy's Rotation) and torch (batched, differentiable).

Local rotations are rotation vectors (axis * angle, radians) of each joint relative to its parent;
joint 0's rotation is the root's world rotation. FK returns world joint positions and, on request,
world rotation matrices and the end-site positions.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from .skeleton import Skeleton


def fk_numpy(
    skeleton: Skeleton,
    rotvecs: np.ndarray,
    root_positions: np.ndarray,
    with_end_sites: bool = False,
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World joint positions [..., J, 3] and world rotation matrices [..., J, 3, 3].

    `rotvecs` is [..., J, 3]; `root_positions` is [..., 3]. With `with_end_sites`, also returns the
    end-site positions [..., E, 3].
    """
    rotvecs = np.asarray(rotvecs, dtype=np.float64)
    lead = rotvecs.shape[:-2]
    nj = skeleton.num_joints
    local = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_matrix().reshape(*lead, nj, 3, 3)
    world_r = np.empty_like(local)
    world_p = np.empty((*lead, nj, 3))
    offsets = skeleton.offsets
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            world_r[..., j, :, :] = local[..., j, :, :]
            world_p[..., j, :] = np.asarray(root_positions, dtype=np.float64) + offsets[j]
        else:
            world_r[..., j, :, :] = world_r[..., p, :, :] @ local[..., j, :, :]
            world_p[..., j, :] = world_p[..., p, :] + world_r[..., p, :, :] @ offsets[j]
    if not with_end_sites:
        return world_p, world_r
    sp = skeleton.end_site_parents()
    so = skeleton.end_site_offsets()
    ends = world_p[..., sp, :] + np.einsum("...eij,ej->...ei", world_r[..., sp, :, :], so)
    return world_p, world_r, ends


def rotvec_to_matrix_torch(rotvec: torch.Tensor) -> torch.Tensor:
    """Rodrigues' formula, [..., 3] -> [..., 3, 3], with a Taylor series near zero angle.

    Written by hand because torch has no rotation library and this runs inside the training graph.
    """
    theta2 = (rotvec * rotvec).sum(-1, keepdim=True)
    small = theta2 < 1e-8
    theta2_safe = torch.where(small, torch.ones_like(theta2), theta2)
    theta = theta2_safe.sqrt()
    a = torch.where(small, 1.0 - theta2 / 6.0, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24.0, (1.0 - torch.cos(theta)) / theta2_safe)
    x, y, z = rotvec.unbind(-1)
    zero = torch.zeros_like(x)
    k = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], dim=-1).reshape(*rotvec.shape[:-1], 3, 3)
    eye = torch.eye(3, dtype=rotvec.dtype, device=rotvec.device).expand_as(k)
    return eye + a[..., None] * k + b[..., None] * (k @ k)


def fk_torch(
    skeleton: Skeleton, rotvecs: torch.Tensor, root_positions: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Batched, differentiable FK: world positions [..., J, 3], rotations [..., J, 3, 3], end sites."""
    local = rotvec_to_matrix_torch(rotvecs)
    offsets = torch.as_tensor(skeleton.offsets, dtype=rotvecs.dtype, device=rotvecs.device)
    rots: list[torch.Tensor] = []
    pos: list[torch.Tensor] = []
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            rots.append(local[..., j, :, :])
            pos.append(root_positions + offsets[j])
        else:
            rots.append(rots[p] @ local[..., j, :, :])
            pos.append(pos[p] + (rots[p] @ offsets[j].unsqueeze(-1)).squeeze(-1))
    world_r = torch.stack(rots, dim=-3)
    world_p = torch.stack(pos, dim=-2)
    if not skeleton.end_sites:
        return world_p, world_r, world_p[..., :0, :]
    sp = torch.as_tensor(skeleton.end_site_parents(), device=rotvecs.device)
    so = torch.as_tensor(skeleton.end_site_offsets(), dtype=rotvecs.dtype, device=rotvecs.device)
    ends = world_p[..., sp, :] + (world_r[..., sp, :, :] @ so.unsqueeze(-1)).squeeze(-1)
    return world_p, world_r, ends
