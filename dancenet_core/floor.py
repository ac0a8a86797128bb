"""Where the floor is under a dancer, from the lowest toe end: a constant height for a clip (`floor_offset`, the
dataset fits) or a height per frame that follows a capture's drift (`floor_track`, the paired dataset and a
motion library's clips). Torch-free: a library build in Blender uses it."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, minimum_filter1d

from .motion import Motion
from .skeleton import TOE_ENDS


def floor_offset(motion: Motion) -> float:
    """Height of the floor under this clip: a low percentile of the lower toe end."""
    toes = motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    return float(np.percentile(toes, 2))


def floor_track(motion: Motion, window_s: float = 2.0, smooth_s: float = 0.5) -> np.ndarray:
    """The floor's height under the dancer, frame by frame [T].

    Most captures drift upward by 0.2-0.5 m over a minute (the toes of a waltz end up 0.4 m above where
    they started). A ballroom dancer has a foot on the floor within any two seconds, so the lowest toe
    end over a 2-s window, smoothed, follows the floor; subtracting it removes the drift.
    """
    toes = motion.end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    low = minimum_filter1d(toes, size=max(1, int(window_s * motion.fps)), mode="nearest")
    return gaussian_filter1d(low, smooth_s * motion.fps, mode="nearest")
