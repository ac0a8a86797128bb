"""Metrics on cases whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from dancenet_core.evaluation.metrics import (
    beat_align_score,
    diversity,
    fid,
    floor_reach,
    foot_sliding,
    frechet_distance,
    jitter,
    longest_freeze_s,
    motion_beats,
    own_song_bas_ratio,
    physical_foot_contact,
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
    # Rhythm hit: music beats 0.2 s from the dance's beats are hits, music beats in a still stretch are not.
    assert rhythm_hit_rate(pos, fps, beats + 0.2) == 1.0
    still = pos.copy()
    still[int(5 * fps) :] = still[int(5 * fps)]  # stops dancing at 5 s
    assert rhythm_hit_rate(still, fps, np.array([1.0, 2.0, 3.0, 7.0, 8.0])) == pytest.approx(0.6)
    # The same dance scores the same at another frame rate (sigma is kept in seconds).
    assert abs(beat_align_score(_bouncing(25.0, beats, 10.0), 25.0, beats) - 1.0) < 0.1


def test_foot_sliding_zero_when_planted_and_full_when_skating() -> None:
    fps, t = 25.0, 100
    toes = np.zeros((t, 2, 3))
    s = foot_sliding(toes, fps, floor=0.0)
    assert s.slide_ratio == 0.0
    assert s.mean_slide_m == 0.0
    assert s.contact_ratio > 0.95
    toes[:, 0, 0] = np.arange(t) * 0.02  # left foot skates at 0.5 m/s
    s = foot_sliding(toes, fps, floor=0.0)
    assert abs(s.slide_ratio - 0.5) < 0.02
    assert abs(s.mean_slide_m - 0.01) < 1e-3


def test_jitter_freeze_and_extent() -> None:
    fps = 25.0
    still = np.zeros((100, 3, 3))
    assert jitter(still, fps) == 0.0
    assert longest_freeze_s(still, fps) == 4.0
    moving = still.copy()
    moving[:, :, 0] = (np.arange(100) / fps)[:, None]  # 1 m/s, no acceleration
    assert jitter(moving, fps) < 1e-9
    assert longest_freeze_s(moving, fps) == 0.0
    assert abs(root_extent_m(moving[:, 0]) - 99 / fps) < 1e-9


def _whitened(n: int, f: int, seed: int = 0) -> np.ndarray:
    """n samples of f features with sample mean exactly 0 and sample covariance exactly the identity."""
    x = np.random.default_rng(seed).standard_normal((n, f))
    x -= x.mean(axis=0)
    return x @ np.linalg.inv(np.linalg.cholesky(np.cov(x, rowvar=False))).T


def test_frechet_distance_of_identical_shifted_and_rescaled_gaussians() -> None:
    z = _whitened(200, 6)
    assert abs(frechet_distance(z, z)) < 1e-8
    shift = np.array([1.0, -2.0, 0.5, 0.0, 0.0, 3.0])
    assert frechet_distance(z, z + shift) == pytest.approx(shift @ shift, rel=1e-9)
    # Gaussians with diagonal covariances a^2 and b^2: |mu|^2 + sum (a - b)^2.
    a, b = np.array([1, 2, 3, 1, 1, 1.0]), np.array([2, 2, 1, 1, 0.5, 1.0])
    assert frechet_distance(z * a, z * b + shift) == pytest.approx(shift @ shift + np.sum((a - b) ** 2), rel=1e-9)


def test_frechet_distance_survives_singular_covariances() -> None:
    x = np.random.default_rng(1).standard_normal((5, 72))  # fewer samples than features, as with few dances
    assert abs(frechet_distance(x, x)) < 1e-3
    shift = np.full(72, 0.5)
    assert frechet_distance(x, x + shift) == pytest.approx(shift @ shift, abs=1e-2)


def test_fid_normalises_by_the_real_set() -> None:
    real = _whitened(100, 4) * [1.0, 2.0, 4.0, 0.5] + 10.0
    assert abs(fid(real, real)) < 1e-8
    shift = np.array([1.0, 1.0, 1.0, 1.0])
    std = real.std(axis=0)
    assert fid(real, real + shift) == pytest.approx(np.sum((shift / std) ** 2), rel=1e-6)
    assert fid(real * 1000, (real + shift) * 1000) == pytest.approx(fid(real, real + shift), rel=1e-6)


def test_diversity_is_the_mean_pairwise_distance() -> None:
    assert diversity(np.ones((5, 3))) == 0.0
    assert diversity(np.array([[0.0, 0.0], [3.0, 4.0]])) == pytest.approx(5.0)
    triangle = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
    assert diversity(triangle) == pytest.approx(1.0)
    reference = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 4.0], [4.0, 4.0]])  # std 2 in each feature
    assert diversity(np.array([[0.0, 0.0], [3.0, 4.0]]), reference=reference) == pytest.approx(2.5)
    with pytest.raises(ValueError):
        diversity(np.ones((1, 3)))


def _feet_and_root(fps: float, seconds: float, foot_speed: float, root_acc: np.ndarray) -> np.ndarray:
    """[T, 12, 3]: a root with constant acceleration root_acc (m/s^2); ankles and feet slide along x at
    foot_speed (m/s)."""
    t = np.arange(int(seconds * fps)) / fps
    pos = np.zeros((len(t), 12, 3))
    pos[:, 0] = 0.5 * np.asarray(root_acc) * t[:, None] ** 2 + [0.0, 0.9, 0.0]
    for j in (7, 8, 10, 11):
        pos[:, j, 0] = foot_speed * t
    return pos


def test_pfc_zero_for_planted_feet_or_a_steady_root() -> None:
    assert physical_foot_contact(_feet_and_root(30.0, 3.0, 0.0, [1.0, 0.0, 0.0]), 30.0) == 0.0
    steady = _feet_and_root(30.0, 3.0, 0.5, [0.0, 0.0, 0.0])
    steady[:, 0, 2] = np.arange(len(steady)) * 0.02  # the root moves, at constant speed
    assert physical_foot_contact(steady, 30.0) == 0.0
    # A root falling freely needs no support: EDGE clamps downward acceleration to 0.
    assert physical_foot_contact(_feet_and_root(30.0, 3.0, 0.5, [0.0, -9.81, 0.0]), 30.0) == 0.0


def test_pfc_of_sliding_feet_under_an_accelerating_root() -> None:
    speed = 0.6  # m/s: 0.02 m per 30-fps frame for each foot
    for fps in (25.0, 30.0, 60.0):
        pfc = physical_foot_contact(_feet_and_root(fps, 3.0, speed, [0.5, 0.0, 0.3]), fps)
        assert pfc == pytest.approx((speed / 30.0) ** 2 * 1e4, rel=1e-6)  # 4.0 at every frame rate
    one_foot = _feet_and_root(30.0, 3.0, speed, [0.5, 0.0, 0.0])
    one_foot[:, 8, 0] = one_foot[:, 11, 0] = 0.0  # the right foot planted: no penalty
    assert physical_foot_contact(one_foot, 30.0) == 0.0


def test_own_song_ratio_tells_a_dance_that_follows_its_song_from_one_that_does_not() -> None:
    """Dances on the beats of their own song score well above 1; the same dances given each other's songs score
    below 1; a song danced twice (two takes) counts once among the others."""
    fps = 25.0
    song_a, song_b = np.arange(1.0, 19.0, 0.5), np.arange(1.25, 19.0, 0.5)  # same tempo, half a beat apart
    on_a, on_b = _bouncing(fps, song_a, 20.0), _bouncing(fps, song_b, 20.0)
    on_b[:, :, 1] = (-np.cos(2 * np.pi * ((np.arange(len(on_b)) + 0.3) / fps - 0.25)) / (2 * np.pi))[:, None]
    ratio = own_song_bas_ratio([on_a, on_a, on_b], fps, [song_a, song_a, song_b])
    assert ratio > 5
    assert own_song_bas_ratio([on_a, on_b], fps, [song_b, song_a]) < 0.2
    assert np.isnan(own_song_bas_ratio([on_a, on_a], fps, [song_a, song_a.copy()]))  # no other song


def test_floor_reach_counts_the_windows_whose_lowest_toe_comes_near_the_floor() -> None:
    fps = 25.0
    low = np.full(250, 0.05)  # 10 s: five 2-s windows, the toe 5 cm up
    assert floor_reach(low, fps) == 0.0
    low[10], low[60] = 0.01, -0.012  # one touch in each of the first two windows, one just under the floor
    low[110] = -0.03  # sinking 3 cm is no better than hovering
    assert floor_reach(low, fps) == pytest.approx(2 / 5)
