"""Foot Constraint Model (supplement, section 3): a small learned post-process against foot sliding.

Three temporal convs (kernel 3, dilations 1, 3, 9) read the lower body's rotations (root channels and
the legs), the toe-end positions and the foot contacts, and output an increment to the lower-body
rotations and the root's height and tilt (not its travel: see `FootChannels.TRAVEL`); the paper chose this
over IK because predicted contacts are not accurate enough for IK (85-90%).
All channels are in the dance model's normalised feature space.

Trained by `training/footfix.py` (`dancenet train footfix`), which says how and what it achieves.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..checkpoint import load_weights, save_weights
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError, first_line
from ..representation import FeatureLayout, Normalizer
from ..runtime.weights import FootChannels
from ..shaping.floor import floor_lift
from ..skeleton import LOWER_BODY, TOE_ENDS, Skeleton
from .kinematics_torch import rotvec_to_matrix_torch

WEIGHTS = WEIGHTS_DIR / "footfix.pt"


class FootConstraintModel(nn.Module):
    """3 temporal convs, kernel 3, dilations 1, 3, 9 (non-causal: the whole dance is known)."""

    def __init__(self, n_in: int, n_out: int, hidden: int = 128) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv1d(n_in, hidden, 3, padding=1, dilation=1), nn.ReLU(),
            nn.Conv1d(hidden, hidden, 3, padding=3, dilation=3), nn.ReLU(),
            nn.Conv1d(hidden, n_out, 3, padding=9, dilation=9),
        )  # fmt: skip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x [B, T, n_in] -> increment [B, T, n_out]."""
        return self.net(x.transpose(1, 2)).transpose(1, 2)

class ToeKinematics:
    """World toe-end positions from normalised lower-body channels, differentiable.

    The contact loss needs where the toes really go; decoding integrates the root's steps and turns over
    the window, so a window starts at the origin facing +Z (sliding is about differences, not places).
    """

    def __init__(self, skeleton: Skeleton, norm: Normalizer, ch: FootChannels) -> None:
        self.mean = torch.tensor(norm.mean[ch.lower])
        self.std = torch.tensor(norm.std[ch.lower])
        self.offsets = torch.tensor(skeleton.offsets, dtype=torch.float32)
        self.parents = skeleton.parents
        self.feet = [int(j) for j in skeleton.end_site_parents()[list(TOE_ENDS)]]
        self.toe_offsets = torch.tensor(skeleton.end_site_offsets()[list(TOE_ENDS)], dtype=torch.float32)

    def __call__(self, lower: torch.Tensor) -> torch.Tensor:
        """Normalised lower-body channels [B, T, L] -> toe ends [B, T, 2, 3] (metres, floor at y = 0)."""
        return self.positions(lower)[1]

    def positions(self, lower: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised lower-body channels [B, T, L] -> (lower-body joints [B, T, J, 3], toe ends [B, T, 2, 3])."""
        x = lower * self.std + self.mean
        dyaw = torch.cat([torch.zeros_like(x[:, :1, 3]), x[:, 1:, 3]], 1)
        yaw = torch.cumsum(dyaw, 1)
        prev = yaw - dyaw
        c, s = torch.cos(prev), torch.sin(prev)
        step_x = (c * x[..., 0] + s * x[..., 2])[:, 1:]
        step_z = (-s * x[..., 0] + c * x[..., 2])[:, 1:]
        zero = torch.zeros_like(x[:, :1, 0])
        root = torch.stack([torch.cumsum(torch.cat([zero, step_x], 1), 1), x[..., 1],
                            torch.cumsum(torch.cat([zero, step_z], 1), 1)], -1)
        cy, sy, z, o = torch.cos(yaw), torch.sin(yaw), torch.zeros_like(yaw), torch.ones_like(yaw)
        ry = torch.stack([cy, z, sy, z, o, z, -sy, z, cy], -1).reshape(*yaw.shape, 3, 3)
        swing = torch.stack([x[..., 4], z, x[..., 5]], -1)
        rot = {0: ry @ rotvec_to_matrix_torch(swing)}
        pos = {0: root + self.offsets[0]}
        for i, j in enumerate(LOWER_BODY[1:]):
            p = self.parents[j]
            pos[j] = pos[p] + (rot[p] @ self.offsets[j].unsqueeze(-1)).squeeze(-1)
            rot[j] = rot[p] @ rotvec_to_matrix_torch(x[..., 6 + 3 * i : 9 + 3 * i])
        toes = torch.stack([pos[f] + (rot[f] @ o.unsqueeze(-1)).squeeze(-1)
                            for f, o in zip(self.feet, self.toe_offsets, strict=True)], -2)
        return torch.stack([pos[j] for j in LOWER_BODY], -2), toes

class FootFixer:
    """The shipped Foot Constraint Model with its normaliser and the skeleton it was trained on."""

    def __init__(self, model: FootConstraintModel, normalizer: Normalizer, layout: FeatureLayout,
                 skeleton: Skeleton) -> None:
        self.model = model.eval()
        self.norm = normalizer
        self.layout = layout
        self.skeleton = skeleton
        self.ch = FootChannels.for_layout(layout)
        self.kin = ToeKinematics(skeleton, normalizer, self.ch)

    @torch.no_grad()
    def __call__(self, features: np.ndarray) -> np.ndarray:
        """Unnormalised features [T, D] -> the same with the lower body corrected and no toe below the floor."""
        x = self.norm.normalize(features)
        x[:, self.ch.corrected] += self.model(torch.tensor(x[None, :, self.ch.inputs]))[0].numpy()
        out = self.norm.denormalize(x)
        out[:, 1] += self.floor_lift(x)
        return out

    def floor_lift(self, x: np.ndarray) -> np.ndarray:
        """Root lift [T] (metres) that keeps both toe ends at or above the floor (see `floor.floor_lift`)."""
        return floor_lift(self.kin(torch.tensor(x[None, :, self.ch.lower]))[0, :, :, 1].min(-1).values.numpy())

    def save(self, path: Path, info: dict) -> None:
        save_weights({"state_dict": self.model.state_dict(), "mean": self.norm.mean, "std": self.norm.std,
                      "constant": self.norm.constant, "num_joints": self.layout.num_joints,
                      "num_end_sites": self.layout.num_end_sites, "skeleton_offsets": self.skeleton.offsets,
                      "info": info}, path)

    @classmethod
    def load(cls, path: Path = WEIGHTS) -> FootFixer:
        d = load_weights(path, "Foot Constraint Model weights", "reinstall the package or use --no-footfix")
        try:
            layout = FeatureLayout(d["num_joints"], d["num_end_sites"])
            ch = FootChannels.for_layout(layout)
            model = FootConstraintModel(len(ch.inputs), len(ch.corrected))
            model.load_state_dict(d["state_dict"])
            norm = Normalizer(np.asarray(d["mean"]), np.asarray(d["std"]), np.asarray(d["constant"]))
            return cls(model, norm, layout, Skeleton(np.asarray(d["skeleton_offsets"])))
        except (RuntimeError, KeyError, TypeError, ValueError, AttributeError) as e:
            raise DanceNetError(f"{path} is not a Foot Constraint Model weights file "
                                f"({first_line(e)}); reinstall the package or use --no-footfix") from e
