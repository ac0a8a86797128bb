"""The style classifier's torch networks (the paper's temporal conv + Bi-LSTM and the FC baseline) and the
checkpoints training writes; generation runs the same network in numpy (`runtime/weights.py`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..checkpoint import read_checkpoint, save_weights
from ..music.style import (
    ARCHS,
    CHECKPOINT_FORMAT,
    DEFAULT_WEIGHTS,
    DROPOUT,
    HIDDEN,
    N_INPUTS,
    StyleClassifier,
    weights_inputs,
)


class StyleConvNet(nn.Module):
    """Temporal conv (kernel 2 along time, 1-16-24-32) + Bi-LSTM + FC: the paper's classifier."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT, inputs: int = N_INPUTS) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for i, (cin, cout) in enumerate(((1, 16), (16, 24), (24, 32))):
            stride = (2, 1) if i == 2 else (1, 1)
            layers += [nn.Conv2d(cin, cout, (2, 1), stride=stride), nn.BatchNorm2d(cout), nn.ReLU()]
        self.conv = nn.Sequential(*layers, nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * inputs, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, inputs] classifier input -> [B, n_styles] logits."""
        h = self.conv(x.unsqueeze(1))  # [B, 32, T', inputs]
        h = h.permute(0, 2, 1, 3).flatten(2)  # [B, T', 32 * inputs]
        out, _ = self.lstm(h)
        return self.fc(out.mean(dim=1))

class StyleBaseline(nn.Module):
    """The paper's baseline: the temporal convolutions replaced by a per-frame fully connected layer."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT, inputs: int = N_INPUTS) -> None:
        super().__init__()
        self.fc_in = nn.Sequential(nn.Linear(inputs, 32 * inputs), nn.ReLU(), nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * inputs, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, inputs] classifier input -> [B, n_styles] logits."""
        out, _ = self.lstm(self.fc_in(x))
        return self.fc(out.mean(dim=1))

def build_net(arch: str, n_styles: int, **config: float) -> nn.Module:
    if arch == "conv":
        return StyleConvNet(n_styles, **config)  # type: ignore[arg-type]
    if arch == "baseline":
        return StyleBaseline(n_styles, **config)  # type: ignore[arg-type]
    raise ValueError(f"unknown style architecture {arch!r}; expected one of {ARCHS}")


class StyleModel(StyleClassifier):
    """A trained torch network plus what it needs to be used: style names, window and frame rate."""

    def __init__(self, net: nn.Module, arch: str, styles: Sequence[str], config: dict, meta: dict | None = None):
        super().__init__(styles, config, meta)
        self.net = net.eval()
        self.arch = arch

    def eval_mode(self) -> StyleModel:
        """Back to inference (dropout off, BatchNorm running statistics) after training steps."""
        self.net.eval()
        return self

    @classmethod
    def load(cls, path: str | Path = DEFAULT_WEIGHTS) -> StyleModel:
        ckpt = read_checkpoint(path, CHECKPOINT_FORMAT, "style model", "dancenet train style")
        config = weights_inputs(ckpt["state_dict"], ckpt["config"])
        net = build_net(ckpt["arch"], len(ckpt["styles"]), **config)
        net.load_state_dict(ckpt["state_dict"])
        return cls(net, ckpt["arch"], ckpt["styles"], config, ckpt["meta"])

    def save(self, path: str | Path) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        save_weights({"format": CHECKPOINT_FORMAT, "arch": self.arch, "styles": list(self.styles),
                      "config": self.config, "meta": self.full_meta(), "state_dict": self.net.state_dict()}, path)

    @torch.no_grad()
    def logits(self, x: np.ndarray) -> np.ndarray:
        return self.net(torch.from_numpy(np.ascontiguousarray(x, np.float32))).numpy()
