"""Dance beats: the kinematic velocity of a dance and its local minima, where a dancer marks the beat.

One home for what Bailando's Beat Align Score measures (`evaluation/metrics.py`) and what the motion library cuts
its clips on (`library/analysis.py`). Velocity is smoothed over Bailando's 5 frames at 60 fps (83 ms) at any rate.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

BAS_SMOOTH_S = 5 / 60


def kinematic_velocity(positions: np.ndarray) -> np.ndarray:
    """Mean over joints of each frame's joint displacement [T] (the first frame repeats the second)."""
    v = np.linalg.norm(np.diff(positions, axis=0), axis=-1).mean(axis=1)
    return np.concatenate([v[:1], v])


def local_minima(v: np.ndarray) -> np.ndarray:
    """Indices of strict local minima of a series (the ends never count), as scipy's argrelextrema(v, np.less)."""
    return np.flatnonzero((v[1:-1] < v[:-2]) & (v[1:-1] < v[2:])) + 1


def motion_beats(positions: np.ndarray, fps: float) -> np.ndarray:
    """Dance beats: local minima of the smoothed kinematic velocity, as frame indices."""
    return local_minima(gaussian_filter1d(kinematic_velocity(positions), BAS_SMOOTH_S * fps))
