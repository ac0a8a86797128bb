"""Training windows drawn on the training device: the same windows, weights, mirror and noise as
`data.windows.WindowSampler`, but gathered from tensors that live where the model does.

Why: on a GPU the numpy batch (a Python loop over windows, then normalising and copying) left the GPU waiting
most of the time (about 9 steps/s per process on an H100). Here every sequence is normalised once,
concatenated into one tensor, and a batch is one multinomial draw and one gather.
"""

from __future__ import annotations

import numpy as np
import torch

from ..data.windows import Batch, WindowSampler


class TensorWindows:
    """`WindowSampler.batch` as tensors on `device` (draws from torch's generator, not numpy's)."""

    def __init__(self, sampler: WindowSampler, device: torch.device) -> None:
        norm, layout = sampler.norm, sampler.layout
        lengths = [len(p.motion) for p in sampler.pairs]
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        self.window = sampler.window
        self.device = device
        self.motion = torch.tensor(np.concatenate([norm.normalize(p.motion) for p in sampler.pairs]), device=device)
        self.mirrored = torch.tensor(np.concatenate([norm.normalize(p.mirrored) for p in sampler.pairs]),
                                     device=device)
        self.music = torch.tensor(np.concatenate([p.music for p in sampler.pairs]).astype(np.float32), device=device)
        self.starts = torch.tensor(starts[sampler.index[:, 0]] + sampler.index[:, 1], device=device)
        self.style = torch.tensor([sampler.style_index[sampler.pairs[i].style] for i in sampler.index[:, 0]],
                                  device=device)
        self.weights = torch.tensor(sampler.weights, dtype=torch.float64, device=device)
        cont = torch.zeros(self.motion.shape[1], dtype=torch.bool, device=device)
        cont[layout.continuous] = True
        self.continuous = cont.to(torch.float32)

    def batch(self, size: int, input_noise: float = 0.04, target_noise: float = 0.01,
              mirror_prob: float = 0.5) -> Batch:
        """A batch whose fields are tensors on the device (same layout as the numpy one)."""
        picks = torch.multinomial(self.weights, size, replacement=True)
        rows = self.starts[picks, None] + torch.arange(self.window, device=self.device)
        mirror = torch.rand(size, 1, 1, device=self.device) < mirror_prob
        x = torch.where(mirror, self.mirrored[rows], self.motion[rows])
        noisy = x + torch.randn_like(x) * (input_noise * self.continuous)
        target = x + torch.randn_like(x) * (target_noise * self.continuous)
        return Batch(noisy, target, self.music[rows], self.style[picks])
