"""Metrics on cases whose answer is known."""

from __future__ import annotations

import numpy as np

from dancenet_core.metrics import (
    beat_align_score,
    foot_sliding,
    jitter,
    longest_freeze_s,
    motion_beats,
    rhythm_hit_rate,
    root_extent_m,
)


def _bouncing(fps: float, beats_s: np.ndarray, seconds: float) -> np.ndarray:
    """Joints whose speed is |sin|, slowest exactly on the beats (every 0.5 s)."""
    t = (np.arange(int(seconds * fps)) + 0.3) / fps  # off the frame grid, so each minimum is unique
    height = -np.cos(2 * np.pi * t) / (2 * np.pi)  # speed |sin(2 pi t)|: zero every 0.5 s, on the beats
    pos = np.zeros((len(t), 4, 3))
    pos[:, :, 1] = height[:, None]
    return pos


def test_beat_align_score_is_one_on_the_beat_and_low_off_it() -> None:
    fps, beats = 60.0, np.arange(1.0, 9.0, 0.5)
    pos = _bouncing(fps, beats, 10.0)
    dance = motion_beats(pos, fps) / fps
    assert np.abs(dance[:, None] - beats[None]).min(0).max() < 1.5 / fps  # minima on the beats
    assert beat_align_score(pos, fps, beats) > 0.95
    assert rhythm_hit_rate(pos, fps, beats) == 1.0
    assert beat_align_score(pos, fps, beats + 0.25) < 0.05  # half a beat off
    # The same dance scores the same at another frame rate (sigma is kept in seconds).
    assert abs(beat_align_score(_bouncing(25.0, beats, 10.0), 25.0, beats) - 1.0) < 0.1


def test_foot_sliding_zero_when_planted_and_full_when_skating() -> None:
    fps, t = 25.0, 100
    toes = np.zeros((t, 2, 3))
    s = foot_sliding(toes, fps, floor=0.0)
    assert s.slide_ratio == 0.0 and s.mean_slide_m == 0.0 and s.contact_ratio > 0.95
    toes[:, 0, 0] = np.arange(t) * 0.02  # left foot skates at 0.5 m/s
    s = foot_sliding(toes, fps, floor=0.0)
    assert abs(s.slide_ratio - 0.5) < 0.02 and abs(s.mean_slide_m - 0.01) < 1e-3


def test_jitter_freeze_and_extent() -> None:
    fps = 25.0
    still = np.zeros((100, 3, 3))
    assert jitter(still, fps) == 0.0 and longest_freeze_s(still, fps) == 4.0
    moving = still.copy()
    moving[:, :, 0] = (np.arange(100) / fps)[:, None]  # 1 m/s, no acceleration
    assert jitter(moving, fps) < 1e-9 and longest_freeze_s(moving, fps) == 0.0
    assert abs(root_extent_m(moving[:, 0]) - 99 / fps) < 1e-9
