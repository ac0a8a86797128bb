"""Forward kinematics in torch: batched and differentiable, for the skeleton fit and the foot model's losses.
Same conventions as `kinematics.fk_numpy` (rotation vectors relative to the parent, joint 0 the root's)."""

from __future__ import annotations

import torch

from ..skeleton import Skeleton


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
