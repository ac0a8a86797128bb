"""Linear resampling of frame series: one helper for music features, activations and joint positions."""

from __future__ import annotations

import numpy as np


def interp_frames(frames: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Frames [T, ...] linearly interpolated at fractional frame `positions` [N] (held at the ends), as
    float64 [N, ...]: every channel by `np.interp`, so the numbers are the same wherever it is used."""
    flat = frames.reshape(len(frames), -1)
    src = np.arange(len(frames))
    out = np.stack([np.interp(positions, src, flat[:, k]) for k in range(flat.shape[1])], axis=-1)
    return out.reshape(len(positions), *frames.shape[1:])


def stretch_frames(frames: np.ndarray, n: int) -> np.ndarray:
    """Frames [T, ...] resampled to `n` frames, first and last aligned (float64)."""
    return interp_frames(frames, np.linspace(0, len(frames) - 1, n))
