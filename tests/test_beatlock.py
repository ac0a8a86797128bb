"""The beat lock: a made-up dance whose beats drift against its song's lands them on the song's beats within the
real-time limit, its length, ends and kept frames kept; the shipped model's dance follows its song's beats more
with it than without, and turning it off leaves the dance as the engine samples it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancenet_core.beats import motion_beats
from dancenet_core.constants import WARP_RANGE
from dancenet_core.evaluation.metrics import beat_align_score
from dancenet_core.motion import Motion
from dancenet_core.representation import decode, encode, start_pose
from dancenet_core.shaping.beatlock import beat_warp, lock_to_beats
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

FPS = 25.0
SONG = Path(__file__).resolve().parents[1] / "examples" / "example_song.ogg"


def _swinging(seconds: float = 20.0, beat_s: float = 0.5) -> Motion:
    """Arms swinging and a body gliding forward at 0.3 m/s: the joints stop (a dance beat) about every `beat_s`,
    from 20 to 140 ms late, the lag drifting (at most 8% faster or slower than the beat)."""
    t = np.arange(int(seconds * FPS)) / FPS
    rot = np.zeros((len(t), 55, 3))
    swing = 0.8 * np.cos(np.pi * (t - 0.08 - 0.06 * np.sin(2 * np.pi * t / 5)) / beat_s)
    rot[:, JOINT_INDEX["left_shoulder"], 2] = swing
    rot[:, JOINT_INDEX["right_shoulder"], 2] = -swing
    root = np.stack([np.zeros(len(t)), np.full(len(t), 0.9), 0.3 * t], -1)
    return Motion(rot, root, FPS, DEFAULT_SKELETON)


def _bas(m: Motion, beats_s: np.ndarray) -> float:
    return beat_align_score(m.positions()[:, :BODY_JOINTS], m.fps, beats_s)


def _locked(m: Motion, beats_s: np.ndarray, keep: int = 0) -> tuple[Motion, np.ndarray]:
    """`m` locked to `beats_s` through its features, as generation locks them, and the warp."""
    feats, src = lock_to_beats(encode(m), FPS, m.skeleton, beats_s, keep)
    return decode(feats, FPS, m.skeleton, *start_pose(m)), src


def test_the_warp_lands_dance_beats_on_song_beats_within_the_limit() -> None:
    rng = np.random.default_rng(0)
    frames = 600
    song = np.arange(10.3, frames - 5, 12.5)
    # The dance's beats up to 4 frames early or late, drifting (at most 8% slower or faster), a little uneven.
    dance = np.round(song + 4 * np.sin(2 * np.pi * song / 300) + rng.normal(0, 0.3, len(song)))
    src = beat_warp(dance, song, frames)
    assert len(src) == frames and src[0] == 0 and src[-1] == frames - 1
    assert np.abs(np.diff(src) - 1).max() <= WARP_RANGE + 1e-9
    # The source frame each song beat plays (the warp's corners fall between frames: within a tenth of one).
    landed = np.interp(song, np.arange(frames), src)
    hit = np.abs(landed[:, None] - dance[None]).min(axis=1) < 0.1
    assert hit.mean() > 0.8
    kept = beat_warp(dance, song, frames, keep=100)
    np.testing.assert_array_equal(kept[:101], np.arange(101))
    assert np.abs(np.diff(kept) - 1).max() <= WARP_RANGE + 1e-9
    # Beats that only a faster warp could reach are left where they are: no warp at all here.
    np.testing.assert_array_equal(beat_warp(dance, song, frames, max_warp=0.0), np.arange(frames))
    np.testing.assert_array_equal(beat_warp(dance, song[:1], frames), np.arange(frames))  # one beat: no tempo


def test_a_dance_drifting_off_its_beats_is_locked_onto_them() -> None:
    m = _swinging()
    beats = np.arange(0.5, m.duration, 0.5)
    locked, src = _locked(m, beats)
    assert locked.num_frames == m.num_frames
    assert _bas(m, beats) < 0.4 and _bas(locked, beats) > 0.8
    assert np.abs(np.diff(src) - 1).max() <= WARP_RANGE + 1e-9
    # The path across the floor is the dance's: it starts and ends where it did and goes the same way.
    np.testing.assert_allclose(locked.root_positions[[0, -1]], m.root_positions[[0, -1]], atol=1e-5)
    assert (np.diff(locked.root_positions[:, 2]) > 0).all() and np.abs(locked.root_positions[:, 0]).max() < 1e-5
    speed = np.diff(locked.root_positions[:, 2]) * FPS
    assert speed.min() >= 0.3 * (1 - WARP_RANGE) - 1e-4 and speed.max() <= 0.3 * (1 + WARP_RANGE) + 1e-4
    kept, _ = _locked(m, beats, keep=100)
    np.testing.assert_allclose(kept.rotations[:100], m.rotations[:100], atol=1e-6)  # float32 features
    assert len(motion_beats(kept.positions()[:, :BODY_JOINTS], FPS)) == len(
        motion_beats(m.positions()[:, :BODY_JOINTS], FPS))  # the same moves, retimed


def test_the_shipped_model_follows_its_songs_beats_with_the_lock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Generate Dance with the real model, the lock on (the default) and off, and a continued dance with it on."""
    from dancenet_core.cli import build_parser
    from dancenet_core.engines import dancenet
    from dancenet_core.generate import generate_dance
    from dancenet_core.request import DanceRequest, options_from

    argv = ["generate", str(SONG), "-o", "out", "--no-beat-lock"]
    assert options_from(build_parser(argv).parse_args(argv))["beat_lock"] is False
    on = generate_dance(DanceRequest(SONG, seed=3, end_s=20.0, takes=2))
    calls, lock = [], dancenet.lock_beats
    monkeypatch.setattr(dancenet, "lock_beats", lambda *a: calls.append(a[3:]) or lock(*a))
    off = generate_dance(DanceRequest(SONG, seed=3, end_s=20.0, takes=2, beat_lock=False))
    assert calls == []  # off: the dance as sampled and cleaned, not warped
    for a, b in zip(on.motions, off.motions, strict=True):
        assert a.num_frames == b.num_frames and not np.array_equal(a.rotations, b.rotations)
    assert np.mean([_bas(m, on.beat_times) for m in on.motions]) > 1.3 * np.mean(
        [_bas(m, off.beat_times) for m in off.motions])
    more = generate_dance(DanceRequest(SONG, seed=4, end_s=20.0, continue_from=on.motions[0], at_s=8.0))
    assert calls == [(200,)]  # continued: locked after the kept frames
    np.testing.assert_array_equal(more.motions[0].rotations[:200], on.motions[0].rotations[:200])
