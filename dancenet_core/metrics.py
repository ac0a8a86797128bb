"""Dance metrics as the field computes them (see REFERENCE.md section 2), on world joint positions.

Time constants are in seconds, so a metric means the same at 25, 30 or 60 fps: Bailando's Beat Align
Score uses sigma = 3 frames at 60 fps (50 ms) and smooths velocity with sigma = 5 frames (83 ms); we keep
those durations at any frame rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import argrelextrema

BAS_SIGMA_S = 3 / 60
BAS_SMOOTH_S = 5 / 60
HIT_WINDOW_S = 0.25

# Foot contact and sliding, after Lodge's foot_skating: toe within 5 cm of the floor; sliding above 1 cm
# per frame at 25 fps = 0.25 m/s of horizontal toe speed. Lodge also asks the ankle to be within 8 cm;
# ballroom dancers stand on the balls of their feet (our capture's planted ankles sit 8-15 cm up), so
# the toe alone decides here.
CONTACT_TOE_M = 0.05
SLIDE_SPEED_MPS = 0.25


def kinematic_velocity(positions: np.ndarray) -> np.ndarray:
    """Mean over joints of each frame's joint displacement [T] (the first frame repeats the second)."""
    v = np.linalg.norm(np.diff(positions, axis=0), axis=-1).mean(axis=1)
    return np.concatenate([v[:1], v])


def motion_beats(positions: np.ndarray, fps: float) -> np.ndarray:
    """Dance beats: local minima of the smoothed kinematic velocity, as frame indices."""
    v = gaussian_filter1d(kinematic_velocity(positions), BAS_SMOOTH_S * fps)
    return argrelextrema(v, np.less)[0]


def _beat_distances(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> np.ndarray:
    """For each music beat within the dance, the distance (s) to the nearest dance beat; empty if none."""
    duration = len(positions) / fps
    beats = np.asarray(music_beats_s)
    beats = beats[(beats >= 0) & (beats < duration)]
    dance = motion_beats(positions, fps) / fps
    if len(beats) == 0 or len(dance) == 0:
        return np.zeros(0)
    return np.abs(beats[:, None] - dance[None, :]).min(axis=1)


def beat_align_score(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> float:
    """Bailando's BAS: mean over music beats of exp(-d^2 / 2 sigma^2), d = distance to the nearest dance beat."""
    d = _beat_distances(positions, fps, music_beats_s)
    return float(np.mean(np.exp(-(d**2) / (2 * BAS_SIGMA_S**2)))) if len(d) else 0.0


def rhythm_hit_rate(positions: np.ndarray, fps: float, music_beats_s: np.ndarray) -> float:
    """The paper's rhythm hit rate: share of music beats with a dance beat within 0.25 s."""
    d = _beat_distances(positions, fps, music_beats_s)
    return float(np.mean(d <= HIT_WINDOW_S)) if len(d) else 0.0


@dataclass
class FootSliding:
    slide_ratio: float  # share of contact frames whose toe moves faster than SLIDE_SPEED_MPS
    mean_slide_m: float  # mean horizontal toe travel per contact frame (metres)
    contact_ratio: float  # share of foot-frames in contact


def foot_sliding(toes: np.ndarray, fps: float, floor: float | None = None) -> FootSliding:
    """Sliding of feet in contact. toes: [T, 2, 3] world positions of the toe ends (left, right)."""
    if floor is None:
        floor = float(np.percentile(toes[:, :, 1].min(axis=1), 2))
    step = np.zeros(toes.shape[:2])
    step[1:] = np.linalg.norm(np.diff(toes[:, :, [0, 2]], axis=0), axis=-1)
    contact = toes[:, :, 1] <= floor + CONTACT_TOE_M
    contact[0] = False
    n = contact.sum()
    if n == 0:
        return FootSliding(0.0, 0.0, 0.0)
    slide = step[contact] * fps > SLIDE_SPEED_MPS
    return FootSliding(float(slide.mean()), float(step[contact].mean()), float(contact.mean()))


def jitter(positions: np.ndarray, fps: float) -> float:
    """Mean joint acceleration magnitude (m/s^2)."""
    acc = np.diff(positions, n=2, axis=0) * fps * fps
    return float(np.linalg.norm(acc, axis=-1).mean())


def longest_freeze_s(positions: np.ndarray, fps: float, speed_mps: float = 0.05) -> float:
    """Longest stretch (seconds) in which the mean joint speed stays below `speed_mps`."""
    still = kinematic_velocity(positions) * fps < speed_mps
    best = run = 0
    for s in still:
        run = run + 1 if s else 0
        best = max(best, run)
    return best / fps


def root_extent_m(root: np.ndarray) -> float:
    """Largest horizontal distance of the root from where it started."""
    return float(np.linalg.norm(root[:, [0, 2]] - root[0, [0, 2]], axis=-1).max())
