"""DanceNet's sizes and settings, apart from the torch network (`nets/dancenet.py`), so that the numpy
runtime (`runtime/weights.py`) reads a checkpoint's configuration without torch."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..music.features import FEATURE_SPEC, N_FEATURES


@dataclass
class DanceNetConfig:
    """Sizes and settings; saved with the weights so a checkpoint rebuilds its own network."""

    motion_dim: int  # size of one frame's feature vector (representation.FeatureLayout.size)
    continuous_dim: int  # channels modelled by the mixture (the rest are foot contacts)
    styles: list[str] = field(default_factory=list)
    fps: float = 25.0
    music_dim: int = N_FEATURES  # = music_spec's dim
    music_code: int = 30
    music_hidden: int = 64
    music_window: int = 200  # frames (8 s at 25 fps)
    music_overlap: int = 50  # frames (2 s) when stitching windows at inference
    style_dim: int = 5
    motion_channels: int = 256
    residual_channels: int = 64
    skip_channels: int = 256
    layers: int = 20
    dilation_cycle: int = 5  # dilations 1, 2, 4, 8, 16 repeated
    kernel_size: int = 2
    mixtures: int = 1
    # Each component's mean is predicted as a change from the input frame (True) or outright (False, every
    # shipped model). A 64-channel residual stack cannot carry all 183 channels of the current frame to its
    # output: the first model's root deltas came out at half the dancer's speed (R^2 0.42 where copying the
    # previous frame scores 0.97). Predicting the change passes the frame through (R^2 0.97 from the start),
    # but free-running such a model drifts away within seconds (docs/experiments.md): an option, off by default.
    residual_output: bool = False
    # A linear path from the input frame straight to every output, beside the stack (starts at zero). It
    # carries what the 64 residual channels lose (the root's steps) while the outputs stay absolute, so a
    # learned, damped copy replaces residual_output's exact one (which drifts when free-running).
    input_skip: bool = False
    min_log_sigma: float = float(np.log(0.03))
    dropout_music: float = 0.1
    input_dropout: float = 0.4
    # Ablations of the paper's Table 3/4 (the shipped model uses the defaults): "gmm" or "mse" loss;
    # "context" (conv + Bi-LSTM) or "frame" (a per-frame linear map, no musical context) music encoder.
    loss: str = "gmm"
    music_encoder: str = "context"
    music_features: str = "onset_beat_chroma"  # or "mel" (music_dim MEL_BANDS)
    # The music features trained on (music.features.FeatureSpec.to_dict()), checked at generation. A config saved
    # before it was recorded reads as this version's spec, the one such weights were trained on.
    music_spec: dict = field(default_factory=FEATURE_SPEC.to_dict)

    @property
    def dilations(self) -> list[int]:
        return [2 ** (i % self.dilation_cycle) for i in range(self.layers)]

    @property
    def receptive_field(self) -> int:
        return 1 + (self.kernel_size - 1) * sum(self.dilations)

    def to_dict(self) -> dict:
        return asdict(self)
