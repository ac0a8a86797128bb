"""Musical style classifier (paper section 4.2) and its FC + Bi-LSTM baseline: inference (training is
`training/style.py`).

The classifier sees 30-second windows of a song's [T, 15] classifier input (10 fps; `classifier_input`) as a
one-channel image:
three Conv2d layers with (2, 1) kernels along time, channels 1-16-24-32 (the last with stride 2, as in the
authors' music encoder), BatchNorm and ReLU, then a Bi-LSTM over time and a fully connected layer on its
time-averaged output. A song's style is the mean of its windows' probabilities. Style names live in the
checkpoint's metadata, never in code, so a model trained on other styles needs no code change.

The classifier input is the music features with the beat and downbeat activation columns replaced by a bump of
fixed height at each beat and downbeat that madmom's DBN tracked: sampled at 10 fps, the 100-fps activations
miss many of their peaks (a song's highest sampled beat value ranges 0.24-0.93 on the training songs), while
the tracked beats carry tempo and metre (3 beats a bar for waltz) intact. DanceNet's own input is unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..checkpoint import read_checkpoint, save_weights
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from .features import BEAT_COL, DOWNBEAT_COL, FEATURE_VERSION, FPS, N_FEATURES, MusicAnalysis

DEFAULT_WEIGHTS = WEIGHTS_DIR / "style_classifier.pt"
BASELINE_WEIGHTS = WEIGHTS_DIR / "style_baseline.pt"
CHECKPOINT_FORMAT = "dancenet-style-2"  # 2: beat and downbeat columns are DBN bumps (`classifier_input`)

WINDOW_S = 30.0  # the paper's window: style is not decided by a 2-3 s clip

HOP_S = 5.0  # between windows when a whole song is classified

ARCHS = ("conv", "baseline")
# Network sizes chosen on training songs held out by song (`dancenet train style --validate`), never on the test split.
HIDDEN = 32

DROPOUT = 0.3
# Bump width: a beat between two frames still shows at exp(-1/8) = 0.88, and bumps of the fastest songs
# (190 bpm, 3.2 frames apart) dip to 0.28 between beats.
BUMP_SIGMA_FRAMES = 1.0


def bump_track(positions: np.ndarray, num_frames: int) -> np.ndarray:
    """[num_frames] float32 with a Gaussian bump of height 1 at each (fractional) frame position, overlapping
    bumps joined by their maximum: every beat shows at nearly full height, whatever the frame grid."""
    p = np.concatenate([[-np.inf], np.sort(np.asarray(positions, np.float64)), [np.inf]])
    grid = np.arange(num_frames, dtype=np.float64)
    i = np.searchsorted(p, grid)
    nearest = np.minimum(grid - p[i - 1], p[i] - grid)
    return np.exp(-0.5 * (nearest / BUMP_SIGMA_FRAMES) ** 2).astype(np.float32)

def classifier_input(analysis: MusicAnalysis) -> np.ndarray:
    """[T, 15] input of the style classifier: the music features, with the beat and downbeat activations
    replaced by bumps at the DBN's beat and downbeat times (see the module docstring for why)."""
    x = analysis.features.astype(np.float32, copy=True)
    x[:, BEAT_COL] = bump_track(analysis.beat_times * analysis.fps, len(x))
    x[:, DOWNBEAT_COL] = bump_track(analysis.downbeat_times * analysis.fps, len(x))
    return x

class StyleConvNet(nn.Module):
    """Temporal conv (kernel 2 along time, 1-16-24-32) + Bi-LSTM + FC: the paper's classifier."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for i, (cin, cout) in enumerate(((1, 16), (16, 24), (24, 32))):
            stride = (2, 1) if i == 2 else (1, 1)
            layers += [nn.Conv2d(cin, cout, (2, 1), stride=stride), nn.BatchNorm2d(cout), nn.ReLU()]
        self.conv = nn.Sequential(*layers, nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * N_FEATURES, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, 15] features -> [B, n_styles] logits."""
        h = self.conv(x.unsqueeze(1))  # [B, 32, T', 15]
        h = h.permute(0, 2, 1, 3).flatten(2)  # [B, T', 32 * 15]
        out, _ = self.lstm(h)
        return self.fc(out.mean(dim=1))

class StyleBaseline(nn.Module):
    """The paper's baseline: the temporal convolutions replaced by a per-frame fully connected layer."""

    def __init__(self, n_styles: int, hidden: int = HIDDEN, dropout: float = DROPOUT) -> None:
        super().__init__()
        self.fc_in = nn.Sequential(nn.Linear(N_FEATURES, 32 * N_FEATURES), nn.ReLU(), nn.Dropout(dropout))
        self.lstm = nn.LSTM(32 * N_FEATURES, hidden, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, n_styles)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T, 15] features -> [B, n_styles] logits."""
        out, _ = self.lstm(self.fc_in(x))
        return self.fc(out.mean(dim=1))

def build_net(arch: str, n_styles: int, **config: float) -> nn.Module:
    if arch == "conv":
        return StyleConvNet(n_styles, **config)  # type: ignore[arg-type]
    if arch == "baseline":
        return StyleBaseline(n_styles, **config)  # type: ignore[arg-type]
    raise ValueError(f"unknown style architecture {arch!r}; expected one of {ARCHS}")

def window_starts(num_frames: int, window: int, hop: int) -> np.ndarray:
    """Starts of windows every `hop` frames, plus one flush with the end so the tail counts too;
    a song shorter than a window is one shorter window."""
    if num_frames <= window:
        return np.zeros(1, dtype=np.int64)
    starts = np.arange(0, num_frames - window + 1, hop)
    if starts[-1] != num_frames - window:
        starts = np.append(starts, num_frames - window)
    return starts

@dataclass
class StyleResult:
    """A song's style: mean window probabilities, and each window's own."""

    styles: tuple[str, ...]
    probabilities: np.ndarray  # [S]
    window_starts_s: np.ndarray  # [W]
    window_probabilities: np.ndarray  # [W, S]
    window_s: float

    @property
    def style(self) -> str:
        return self.styles[int(np.argmax(self.probabilities))]

    def window_styles(self) -> list[str]:
        return [self.styles[int(i)] for i in np.argmax(self.window_probabilities, axis=1)]

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "style": self.style,
            "probabilities": {s: round(float(p), 4) for s, p in zip(self.styles, self.probabilities, strict=True)},
            "window_s": self.window_s,
            "windows": [
                {
                    "start_s": round(float(t), 2),
                    "style": s,
                    "probabilities": {n: round(float(p), 4) for n, p in zip(self.styles, probs, strict=True)},
                }
                for t, s, probs in zip(
                    self.window_starts_s, self.window_styles(), self.window_probabilities, strict=True
                )
            ],
        }

class StyleModel:
    """A trained network plus what it needs to be used: style names, window and frame rate."""

    def __init__(self, net: nn.Module, arch: str, styles: Sequence[str], config: dict, meta: dict | None = None):
        self.net = net.eval()
        self.arch = arch
        self.styles = tuple(styles)
        self.config = dict(config)
        self.meta = dict(meta or {})
        self.fps = int(self.meta.get("fps", FPS))
        self.window = int(round(float(self.meta.get("window_s", WINDOW_S)) * self.fps))
        self.hop = int(round(float(self.meta.get("hop_s", HOP_S)) * self.fps))

    def eval_mode(self) -> StyleModel:
        """Back to inference (dropout off, BatchNorm running statistics) after training steps."""
        self.net.eval()
        return self

    @classmethod
    def load(cls, path: str | Path = DEFAULT_WEIGHTS) -> StyleModel:
        ckpt = read_checkpoint(path, CHECKPOINT_FORMAT, "style model", "dancenet train style")
        net = build_net(ckpt["arch"], len(ckpt["styles"]), **ckpt["config"])
        net.load_state_dict(ckpt["state_dict"])
        return cls(net, ckpt["arch"], ckpt["styles"], ckpt["config"], ckpt["meta"])

    def save(self, path: str | Path) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        meta = {
            **self.meta,
            "fps": self.fps,
            "window_s": self.window / self.fps,
            "hop_s": self.hop / self.fps,
            "feature_version": FEATURE_VERSION,
        }
        save_weights(
            {
                "format": CHECKPOINT_FORMAT,
                "arch": self.arch,
                "styles": list(self.styles),
                "config": self.config,
                "meta": meta,
                "state_dict": self.net.state_dict(),
            },
            path,
        )

    @torch.no_grad()
    def window_probabilities(self, features: np.ndarray, starts: np.ndarray, batch: int = 64) -> np.ndarray:
        """[W, S] softmax of the windows of `features` starting at `starts`."""
        length = min(self.window, len(features))
        x = torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32))
        out = []
        for i in range(0, len(starts), batch):
            xb = torch.stack([x[s : s + length] for s in starts[i : i + batch]])
            out.append(torch.softmax(self.net(xb), dim=1))
        return torch.cat(out).numpy()

    def classify(self, analysis: MusicAnalysis) -> StyleResult:
        """Style of a whole song from its analysis (features and tracked beats): mean of the windows'
        probabilities (an overconfident window counts at most 1, where in a mean of log-probabilities it could
        veto a style)."""
        features = analysis.features
        if analysis.fps != self.fps or features.ndim != 2 or features.shape[1] != N_FEATURES:
            raise ValueError(
                f"expected [T, {N_FEATURES}] features at {self.fps} fps, got {features.shape} at {analysis.fps}"
            )
        if len(features) < 4:
            raise DanceNetError("the song is too short to classify its style; give at least a few seconds")
        starts = window_starts(len(features), self.window, self.hop)
        probs = self.window_probabilities(classifier_input(analysis), starts)
        return StyleResult(
            self.styles,
            probs.mean(axis=0),
            starts / self.fps,
            probs,
            min(self.window, len(features)) / self.fps,
        )
