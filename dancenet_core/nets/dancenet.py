"""DanceNet (paper section 4.4 and supplement): music context encoder, motion encoder, a stack of gated
dilated residual layers conditioned on music and style, and a decoder to a Gaussian mixture plus
foot-contact logits.

`DanceNet.forward` is the teacher-forced pass used for training; `runtime/sampler.py` generates frame by
frame with cached per-layer queues, `naive_run` (here) the way it is compared with.
"""

from __future__ import annotations

import copy
from typing import Protocol

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ..runtime.config import DanceNetConfig
from ..runtime.numpy_nets import NumpyDanceNet, fold_batchnorm
from ..runtime.sampler import WindowConditioning


def numpy_state(module: nn.Module) -> dict[str, np.ndarray]:
    """A torch module's state dict as numpy arrays (BatchNorm's step counter left out: inference never reads it)."""
    return {k: v.detach().cpu().numpy() for k, v in module.state_dict().items()
            if not k.endswith("num_batches_tracked")}


class MusicEncoder(nn.Module):
    """Temporal convs (1-16-24-32 channels, kernel 2 in time, as on a 1-channel image) + Bi-LSTM -> code.

    As in the authors' code the last conv has stride 2 in time, so the Bi-LSTM (the costly, sequential
    part on a CPU) runs at half the motion rate; its code is interpolated back to every motion frame.
    """

    def __init__(self, cfg: DanceNetConfig) -> None:
        super().__init__()
        chans = [1, 16, 24, 32]
        self.convs = nn.ModuleList(
            nn.Conv2d(a, b, (2, 1), stride=(2 if k == 2 else 1, 1))
            for k, (a, b) in enumerate(zip(chans[:-1], chans[1:], strict=True))
        )
        self.norms = nn.ModuleList(nn.BatchNorm2d(b) for b in chans[1:])
        self.dropout = nn.Dropout(cfg.dropout_music)
        self.lstm = nn.LSTM(32 * cfg.music_dim, cfg.music_hidden, batch_first=True, bidirectional=True)
        self.out = nn.Linear(2 * cfg.music_hidden, cfg.music_code)

    def forward(self, music: torch.Tensor) -> torch.Tensor:
        """music [B, T, music_dim] at the motion rate -> code [B, T, music_code]."""
        frames = music.shape[1]
        x = music.unsqueeze(1)  # [B, 1, T, F]
        for conv, norm in zip(self.convs, self.norms, strict=True):
            x = self.dropout(F.relu(norm(conv(F.pad(x, (0, 0, 0, 1))))))
        b, c, t, f = x.shape
        h, _ = self.lstm(x.permute(0, 2, 1, 3).reshape(b, t, c * f))
        code = self.out(h).transpose(1, 2)  # [B, code, T / 2]
        return F.interpolate(code, size=frames, mode="linear", align_corners=False).transpose(1, 2)


class FrameMusicEncoder(nn.Module):
    """The ablation without the musical context-aware encoder: each frame's features mapped on their own."""

    def __init__(self, cfg: DanceNetConfig) -> None:
        super().__init__()
        self.out = nn.Linear(cfg.music_dim, cfg.music_code)

    def forward(self, music: torch.Tensor) -> torch.Tensor:
        return self.out(music)


class ResidualLayer(nn.Module):
    """Gated dilated causal conv (separate filter and gate convs), conditioned through 1x1 convs."""

    def __init__(self, cfg: DanceNetConfig, dilation: int) -> None:
        super().__init__()
        r = cfg.residual_channels
        self.dilation = dilation
        self.filter = nn.Conv1d(r, r, cfg.kernel_size, dilation=dilation)
        self.gate = nn.Conv1d(r, r, cfg.kernel_size, dilation=dilation)
        self.cond = nn.Conv1d(cfg.music_code + cfg.style_dim, 2 * r, 1)
        self.res = nn.Conv1d(r, r, 1)
        self.skip = nn.Conv1d(r, cfg.skip_channels, 1)

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        xp = F.pad(x, (self.dilation * (self.filter.kernel_size[0] - 1), 0))  # causal: past frames only
        c_f, c_g = self.cond(cond).chunk(2, dim=1)
        h = torch.tanh(self.filter(xp) + c_f) * torch.sigmoid(self.gate(xp) + c_g)
        return x + self.res(h), self.skip(h)


class DanceNet(nn.Module):
    def __init__(self, cfg: DanceNetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        m, r, s = cfg.motion_channels, cfg.residual_channels, cfg.skip_channels
        self.music_encoder = MusicEncoder(cfg) if cfg.music_encoder == "context" else FrameMusicEncoder(cfg)
        self.style_embedding = nn.Embedding(max(1, len(cfg.styles)), cfg.style_dim)
        self.motion_encoder = nn.Sequential(
            nn.Conv1d(cfg.motion_dim, m, 1), nn.ReLU(), nn.Conv1d(m, m, 1), nn.ReLU(), nn.Conv1d(m, r, 1)
        )
        self.layers = nn.ModuleList(ResidualLayer(cfg, d) for d in cfg.dilations)
        out = output_size(cfg)
        self.decoder = nn.Sequential(nn.ReLU(), nn.Conv1d(s, s, 1), nn.ReLU(), nn.Conv1d(s, out, 1))
        self.input_skip = nn.Conv1d(cfg.motion_dim, out, 1) if cfg.input_skip else None
        # Channels the mixture models (constant ones, e.g. resting fingers, are left out of the loss).
        self.register_buffer("modelled", torch.ones(cfg.continuous_dim, dtype=torch.bool))
        for p in self.parameters():
            if p.dim() > 1:
                nn.init.xavier_normal_(p)
        if self.input_skip is not None:  # starts as the network without it (a warm start keeps its dances)
            nn.init.zeros_(self.input_skip.weight)
            nn.init.zeros_(self.input_skip.bias)

    def conditioning(self, music: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """Music code + style embedding per frame, [B, code + style_dim, T]."""
        code = self.music_encoder(music)
        emb = self.style_embedding(style)[:, None, :].expand(-1, code.shape[1], -1)
        return torch.cat([code, emb], dim=-1).transpose(1, 2)

    def forward_frames(self, motion: torch.Tensor, cond: torch.Tensor, base: torch.Tensor | None = None
                       ) -> torch.Tensor:
        """Teacher-forced pass: frames [B, T, D] and conditioning [B, C, T] -> raw outputs [B, T, out].

        Output t describes frame t + 1; `cond[..., t]` must be the conditioning of frame t + 1. With
        `residual_output`, the means are offsets from `base` (default: the input frames; training passes
        them before input dropout).
        """
        frames = motion.transpose(1, 2)
        x = self.motion_encoder(frames)
        skip = 0.0
        for layer in self.layers:
            x, s = layer(x, cond)
            skip = skip + s
        out = self.decoder(skip)
        if self.input_skip is not None:
            out = out + self.input_skip(frames)
        out = out.transpose(1, 2)
        if not self.cfg.residual_output:
            return out
        k, d = self.cfg.mixtures, self.cfg.continuous_dim
        base = (motion if base is None else base)[..., :d] * self.modelled.to(out.dtype)
        return torch.cat([out[..., :k], out[..., k : k + k * d] + base.repeat(1, 1, k), out[..., k + k * d :]], -1)

    def forward(self, motion: torch.Tensor, music: torch.Tensor, style: torch.Tensor,
                base: torch.Tensor | None = None) -> torch.Tensor:
        """Outputs for frames 1..T-1 given frames 0..T-2 and the music of frames 1..T-1 (`base`: see
        forward_frames, the same length as `motion`)."""
        cond = self.conditioning(music, style)
        return self.forward_frames(motion[:, :-1], cond[..., 1:], None if base is None else base[:, :-1])

    def to_numpy(self) -> NumpyDanceNet:
        """These weights for the numpy runtime (generation without torch), the music encoder's BatchNorm folded
        in float64 (the encoder runs in float64: `NumpyDanceNet.conditioning`)."""
        state = numpy_state(self)
        if self.cfg.music_encoder == "context":
            state = fold_batchnorm(state, [(f"music_encoder.convs.{k}", f"music_encoder.norms.{k}") for k in range(3)],
                                   np.float64)
        return NumpyDanceNet(self.cfg, state)

    def exact_conditioner(self) -> WindowConditioning:
        """Conditioning [B, T, C] of windows of music [B, T, F] and styles [B] as arrays, by a float64 copy of
        this network (why float64: `NumpyDanceNet.conditioning`): `sampler.music_conditioning`'s for torch."""
        exact = copy.deepcopy(self).double().eval()

        def conditioning(music: np.ndarray, style: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                code = exact.conditioning(torch.from_numpy(music).double(), torch.from_numpy(style))
            return code.transpose(1, 2).numpy()

        return conditioning

    def split(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        return split_outputs(out, self.cfg)

    def loss(self, out: torch.Tensor, target: torch.Tensor, music: torch.Tensor) -> tuple[torch.Tensor, dict]:
        """Training loss of `forward`'s outputs against frames 1..T-1 (music unused: a common signature)."""
        return dancenet_loss(self, out, target)


class OutputSizes(Protocol):
    """What the mixture head's layout depends on (DanceNet's config and the GMM baselines' have it)."""

    mixtures: int
    motion_dim: int
    continuous_dim: int


def output_size(cfg: OutputSizes) -> int:
    """Mixture logits, means and log sigmas of the continuous channels, then contact logits."""
    return cfg.mixtures * (1 + 2 * cfg.continuous_dim) + (cfg.motion_dim - cfg.continuous_dim)


def split_outputs(out: torch.Tensor, cfg: OutputSizes) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Raw outputs -> (mixture logits [.., K], means [.., K, D], log sigmas [.., K, D], contact logits)."""
    k, d = cfg.mixtures, cfg.continuous_dim
    logits = out[..., :k]
    mu = out[..., k : k + k * d].unflatten(-1, (k, d))
    log_sigma = out[..., k + k * d : k + 2 * k * d].unflatten(-1, (k, d))
    log_sigma = cfg.min_log_sigma + F.softplus(log_sigma - cfg.min_log_sigma)
    return logits, mu, log_sigma, out[..., k + 2 * k * d :]


def mixture_nll(
    logits: torch.Tensor, mu: torch.Tensor, log_sigma: torch.Tensor, target: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """Negative log-likelihood of `target` [..., D] under the diagonal Gaussian mixture, per modelled channel."""
    z = (target.unsqueeze(-2) - mu) * torch.exp(-log_sigma)
    per_dim = -0.5 * z**2 - log_sigma - 0.5 * float(np.log(2 * np.pi))
    comp = (per_dim * mask).sum(-1) + torch.log_softmax(logits, dim=-1)
    return -torch.logsumexp(comp, dim=-1) / mask.sum()


def dancenet_loss(
    model: nn.Module, out: torch.Tensor, target: torch.Tensor, contact_weight: float = 0.1
) -> tuple[torch.Tensor, dict[str, float]]:
    """Mixture NLL (or, for the MSE ablation, squared error of the mean) + contact_weight x foot-contact BCE
    (the paper's lambda = 0.1). `model` is any network with `cfg`, `modelled` and the shared output layout."""
    logits, mu, log_sigma, contact_logits = split_outputs(out, model.cfg)
    d = model.cfg.continuous_dim
    mask = model.modelled.to(out.dtype)
    bce = F.binary_cross_entropy_with_logits(contact_logits, target[..., d:].clamp(0, 1))
    if model.cfg.loss == "mse":  # the sigma outputs stay untrained; such models are sampled at their mean
        mse = (((mu[..., 0, :] - target[..., :d]) ** 2) * mask).sum(-1).mean() / mask.sum()
        return mse + contact_weight * bce, {"mse": float(mse.detach()), "bce": float(bce.detach())}
    nll = mixture_nll(logits, mu, log_sigma, target[..., :d], mask).mean()
    return nll + contact_weight * bce, {"nll": float(nll.detach()), "bce": float(bce.detach())}


def naive_run(model: DanceNet, first: np.ndarray, cond: np.ndarray, teacher: np.ndarray) -> np.ndarray:
    """The reference way: for each new frame, run the full stack over the last receptive-field frames.

    Feeds `teacher` frames [B, T, D] (sampling does not change the cost); returns the outputs [B, T, O].
    A benchmark and test reference for the cached sampler, never run by generation.
    """
    rf = model.cfg.receptive_field
    bsz, t_total = len(first), len(cond)
    cond_t = torch.tensor(cond, dtype=torch.float32).T.unsqueeze(0).expand(bsz, -1, -1)
    frames = torch.tensor(teacher, dtype=torch.float32)
    with torch.no_grad():
        outs = [model.forward_frames(frames[:, max(0, t - rf) : t], cond_t[..., max(0, t - rf) + 1 : t + 1])[:, -1]
                for t in range(1, t_total)]
    return torch.stack([torch.zeros_like(outs[0])] + outs, 1).numpy()
