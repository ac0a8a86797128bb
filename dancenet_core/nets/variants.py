"""The models of the paper's comparison (Tables 3 and 4) by name: DanceNet, its ablations and the baselines,
built, trained and sampled through one interface so every row is produced the same way."""

from __future__ import annotations

import numpy as np
from torch import nn

from ..music.features import MUSIC_SPECS
from ..runtime.sampler import CachedSampler, Sampling, music_conditioning
from .baselines import KINDS, BaselineConfig, build_baseline
from .dancenet import DanceNet, DanceNetConfig

VARIANTS: dict[str, str] = {
    "dancenet": "DanceNet",
    "dancenet_mse": "DanceNet, MSE loss (no GMM)",
    "dancenet_no_context": "DanceNet without the musical context encoder",
    "dancenet_mel": "DanceNet on the mel spectrum",
    "lstm_gmm": "LSTM with GMM loss [32]",
    "temporal_conv": "Temporal Conv [14]",
    "lstm_autoencoder": "LSTM-autoencoder [46]",
}


def music_features(variant: str) -> str:
    return "mel" if variant == "dancenet_mel" else "onset_beat_chroma"


def build_model(variant: str, motion_dim: int, continuous_dim: int, styles: list[str], window: int,
                mixtures: int = 1, residual_output: bool = False, input_skip: bool = False,
                widths: tuple[int, int, int] | None = None) -> nn.Module:
    """A freshly initialised network for `variant` (see VARIANTS); `mixtures` sizes DanceNet's GMM,
    `residual_output` makes its means changes from the last frame, `input_skip` adds a linear path from
    the input frame to the outputs and `widths` sets the motion/residual/skip channels (DanceNet variants only;
    default the config's)."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {', '.join(VARIANTS)}")
    spec = MUSIC_SPECS[music_features(variant)]
    if variant in KINDS:
        return build_baseline(BaselineConfig(kind=variant, motion_dim=motion_dim, continuous_dim=continuous_dim,
                                             styles=styles, music_dim=spec.dim, music_spec=spec.to_dict(),
                                             music_window=window, loss="gmm" if variant == "lstm_gmm" else "mse"))
    cfg = DanceNetConfig(motion_dim=motion_dim, continuous_dim=continuous_dim, styles=styles, fps=25.0,
                         music_window=window, music_dim=spec.dim, music_features=music_features(variant),
                         music_spec=spec.to_dict(),
                         mixtures=mixtures if variant != "dancenet_mse" else 1, residual_output=residual_output,
                         input_skip=input_skip, loss="mse" if variant == "dancenet_mse" else "gmm",
                         music_encoder="frame" if variant == "dancenet_no_context" else "context")
    if widths:
        cfg.motion_channels, cfg.residual_channels, cfg.skip_channels = widths
    return DanceNet(cfg)


def model_from_config(kind: str, config: dict) -> nn.Module:
    """Rebuild a saved network: `kind` is "dancenet" or one of the baselines' kinds."""
    if kind == "dancenet":
        return DanceNet(DanceNetConfig(**config))
    return build_baseline(BaselineConfig(**config))


def sample_normalized(model: nn.Module, music: np.ndarray, style: int, first: np.ndarray, temperature: float,
                      rng: np.random.Generator) -> np.ndarray:
    """One dance [T, D] (normalised) for music [T, F] at the motion rate, from frame 0 `first` [D].

    MSE-trained models never learned a spread, so they are sampled at their mean whatever the temperature.
    """
    if model.cfg.loss == "mse":
        temperature = 0.0
    if isinstance(model, DanceNet):
        cond = music_conditioning(model, music, style)
        return CachedSampler(model).run(first[None], cond, Sampling(temperature, rng))[0][0]
    return model.generate(music, style, first, temperature, rng)
