"""Forward kinematics in numpy (scipy's Rotation); the torch version (differentiable, for training and the foot
model) is `nets/kinematics_torch.py`, so that writing keyframes in Blender needs no torch.

Local rotations are rotation vectors (axis * angle, radians) of each joint relative to its parent;
joint 0's rotation is the root's world rotation. FK returns world joint positions and, on request,
world rotation matrices and the end-site positions.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .skeleton import Skeleton


def fk_numpy(
    skeleton: Skeleton,
    rotvecs: np.ndarray,
    root_positions: np.ndarray,
    with_end_sites: bool = False,
    joints: int | None = None,
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World joint positions [..., J, 3] and world rotation matrices [..., J, 3, 3].

    `rotvecs` is [..., J, 3]; `root_positions` is [..., 3]. With `with_end_sites`, also returns the
    end-site positions [..., E, 3]. `joints`: only the first this many joints (joints come after their parents,
    so the body's first 22 need none of the hands': a third of the work), without end sites.
    """
    rotvecs = np.asarray(rotvecs, dtype=np.float64)
    lead = rotvecs.shape[:-2]
    nj = skeleton.num_joints if joints is None else joints
    rotvecs = rotvecs[..., :nj, :]
    local = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_matrix().reshape(*lead, nj, 3, 3)
    world_r = np.empty_like(local)
    world_p = np.empty((*lead, nj, 3))
    offsets = skeleton.offsets
    for j, p in enumerate(skeleton.parents[:nj]):
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
