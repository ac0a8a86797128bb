"""The sequence models the paper compares DanceNet with (Table 3), trained on the same data and windows.

- `LstmGmm`: an autoregressive LSTM driven by the music and style (the paper's LSTM [32]), with DanceNet's
  Gaussian-mixture + contact head, since the paper found the LSTM could not learn dance with an MSE loss.
- `TemporalConv`: music -> motion directly by a stack of non-causal temporal convolutions (Ginosar et
  al.'s speech-to-gesture model [14]), MSE loss.
- `LstmAutoencoder`: music -> LSTM -> motion directly, with a music-reconstruction head (Tang et al.'s
  Dance with Melody [46]), MSE loss.

All share DanceNet's output layout (`dancenet.output_size`), loss (`dancenet_loss`) and the call
signatures the trainer and the evaluation use: `forward(motion, music, style)` gives the outputs for
frames 1..T-1, `loss(out, target, music)`, and `generate(music, style, first, sampling)`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass, field

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ..music.features import FEATURE_SPEC, N_FEATURES
from .dancenet import dancenet_loss, output_size, split_outputs

KINDS = ("lstm_gmm", "temporal_conv", "lstm_autoencoder")


@dataclass
class BaselineConfig:
    kind: str  # one of KINDS
    motion_dim: int
    continuous_dim: int
    styles: list[str] = field(default_factory=list)
    fps: float = 25.0
    music_dim: int = N_FEATURES  # = music_spec's dim
    music_features: str = "onset_beat_chroma"
    music_spec: dict = field(default_factory=FEATURE_SPEC.to_dict)  # as DanceNetConfig's
    style_dim: int = 5
    hidden: int = 256
    layers: int = 2
    music_window: int = 200
    mixtures: int = 1
    min_log_sigma: float = float(np.log(0.03))
    input_dropout: float = 0.4
    loss: str = "mse"

    def to_dict(self) -> dict:
        return asdict(self)


class _Baseline(nn.Module):
    def __init__(self, cfg: BaselineConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.style_embedding = nn.Embedding(max(1, len(cfg.styles)), cfg.style_dim)
        self.register_buffer("modelled", torch.ones(cfg.continuous_dim, dtype=torch.bool))

    def control(self, music: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """Music features and style embedding per frame [B, T, music_dim + style_dim]."""
        emb = self.style_embedding(style)[:, None, :].expand(-1, music.shape[1], -1)
        return torch.cat([music, emb], dim=-1)

    def loss(self, out: torch.Tensor, target: torch.Tensor, music: torch.Tensor) -> tuple[torch.Tensor, dict]:
        return dancenet_loss(self, out[..., : output_size(self.cfg)], target)

    def _frames(self, out: torch.Tensor, temperature: float, eps: torch.Tensor) -> torch.Tensor:
        """A frame from raw outputs [B, O]: mean (+ temperature x sigma x eps for GMM), contacts at 0.5."""
        _, mu, log_sigma, contact = split_outputs(out, self.cfg)
        x = mu[:, 0]
        if self.cfg.loss == "gmm" and temperature > 0:
            x = x + torch.exp(log_sigma[:, 0]) * temperature * eps
        x = torch.where(self.modelled, x, torch.zeros_like(x))
        return torch.cat([x, (contact > 0).to(x.dtype)], dim=-1)


class LstmGmm(_Baseline):
    def __init__(self, cfg: BaselineConfig) -> None:
        super().__init__(cfg)
        h = cfg.hidden
        self.motion_encoder = nn.Sequential(nn.Linear(cfg.motion_dim, h), nn.ReLU())
        self.lstm = nn.LSTM(h + cfg.music_dim + cfg.style_dim, h, num_layers=cfg.layers, batch_first=True)
        self.head = nn.Linear(h, output_size(cfg))

    def forward(self, motion: torch.Tensor, music: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        x = torch.cat([self.motion_encoder(motion[:, :-1]), self.control(music, style)[:, 1:]], dim=-1)
        return self.head(self.lstm(x)[0])

    @torch.no_grad()
    def generate(self, music: np.ndarray, style: int, first: np.ndarray, temperature: float,
                 rng: np.random.Generator) -> np.ndarray:
        """Frame by frame, carrying the LSTM state: [T, D] normalised frames from frame 0 `first` [D]."""
        self.eval()
        ctrl = self.control(torch.tensor(music[None], dtype=torch.float32), torch.tensor([style]))
        frames = [torch.tensor(first[None], dtype=torch.float32)]
        eps = torch.tensor(rng.standard_normal((len(music), self.cfg.continuous_dim)), dtype=torch.float32)
        state = None
        for t in range(1, len(music)):
            x = torch.cat([self.motion_encoder(frames[-1]), ctrl[:, t]], dim=-1)[:, None]
            h, state = self.lstm(x, state)
            frames.append(self._frames(self.head(h[:, 0]), temperature, eps[t : t + 1]))
        return torch.cat(frames).numpy()


class _MusicToMotion(_Baseline, ABC):
    """Non-autoregressive: the whole dance from the whole song at once (the first frame is not used)."""

    @abstractmethod
    def body(self, ctrl: torch.Tensor) -> torch.Tensor:
        """Control [B, T, C] -> raw outputs [B, T, O] for every frame."""

    def forward(self, motion: torch.Tensor, music: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        return self.body(self.control(music, style))[:, 1:]

    @torch.no_grad()
    def generate(self, music: np.ndarray, style: int, first: np.ndarray, temperature: float,
                 rng: np.random.Generator) -> np.ndarray:
        self.eval()
        out = self.body(self.control(torch.tensor(music[None], dtype=torch.float32), torch.tensor([style])))
        eps = torch.zeros(len(music), self.cfg.continuous_dim)
        return self._frames(out[0, :, : output_size(self.cfg)], 0.0, eps).numpy()


class TemporalConv(_MusicToMotion):
    def __init__(self, cfg: BaselineConfig) -> None:
        super().__init__(cfg)
        h, layers = cfg.hidden, []
        chans = [cfg.music_dim + cfg.style_dim] + [h] * (2 * cfg.layers + 2)
        for a, b in zip(chans[:-1], chans[1:], strict=True):
            layers += [nn.Conv1d(a, b, 5, padding=2), nn.BatchNorm1d(b), nn.ReLU()]
        self.convs = nn.Sequential(*layers)
        self.head = nn.Conv1d(h, output_size(cfg), 1)

    def body(self, ctrl: torch.Tensor) -> torch.Tensor:
        return self.head(self.convs(ctrl.transpose(1, 2))).transpose(1, 2)


class LstmAutoencoder(_MusicToMotion):
    def __init__(self, cfg: BaselineConfig) -> None:
        super().__init__(cfg)
        h = cfg.hidden
        self.encoder = nn.Sequential(nn.Linear(cfg.music_dim + cfg.style_dim, h), nn.ReLU())
        self.lstm = nn.LSTM(h, h, num_layers=cfg.layers, batch_first=True)
        self.head = nn.Linear(h, output_size(cfg))
        self.reconstruct = nn.Linear(h, cfg.music_dim)  # the autoencoder's music reconstruction

    def body(self, ctrl: torch.Tensor) -> torch.Tensor:
        h = self.lstm(self.encoder(ctrl))[0]
        return torch.cat([self.head(h), self.reconstruct(h)], dim=-1)

    def loss(self, out: torch.Tensor, target: torch.Tensor, music: torch.Tensor) -> tuple[torch.Tensor, dict]:
        total, parts = super().loss(out, target, music)
        rec = F.mse_loss(out[..., output_size(self.cfg) :], music)
        return total + rec, parts | {"reconstruction": float(rec.detach())}


def build_baseline(cfg: BaselineConfig) -> _Baseline:
    model = {"lstm_gmm": LstmGmm, "temporal_conv": TemporalConv, "lstm_autoencoder": LstmAutoencoder}[cfg.kind](cfg)
    for p in model.parameters():
        if p.dim() > 1:
            nn.init.xavier_normal_(p)
    return model
