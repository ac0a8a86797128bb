"""Training data: the skeleton fit on real capture, the mirror fix, music/motion alignment, windows."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancenet_core.data.build import PairedSequence
from dancenet_core.data.dance_with_melody import load_positions, read_manifest
from dancenet_core.data.fit import fit_errors, fit_sequence
from dancenet_core.data.windows import WindowSampler
from dancenet_core.kinematics import fk_numpy
from dancenet_core.motion import Motion
from dancenet_core.music.features import music_at_frames
from dancenet_core.representation import FeatureLayout, Normalizer, encode
from dancenet_core.skeleton import BODY_JOINTS
from dancenet_core.skeleton import JOINT_INDEX as J


@pytest.fixture(scope="module")
def fitted(shared_data) -> dict:
    seqs = {s.seq: s for s in read_manifest(shared_data)}
    out = {}
    for name in ("DANCE_W_1", "DANCE_C_2"):
        pos = load_positions(seqs[name])[300:800]
        motion, targets = fit_sequence(pos, 25.0, steps=150)
        out[name] = (motion, fit_errors(motion, pos, targets))
    return out


@pytest.mark.data  # fits whole capture sequences
@pytest.mark.parametrize("name", ["DANCE_W_1", "DANCE_C_2"])
def test_fit_error_bounds_on_real_sequences(fitted: dict, name: str) -> None:
    _, err = fitted[name]
    assert err.mean() < 0.03, f"mean fit error {err.mean() * 100:.2f} cm"
    assert np.percentile(err, 95) < 0.07, f"p95 fit error {np.percentile(err, 95) * 100:.2f} cm"


@pytest.mark.data
def test_closed_hold_waltz_has_right_hand_raised_and_head_turned_left(fitted: dict) -> None:
    """The mirror fix: in the standard closed hold the right hand is up and the head turns left."""
    motion, _ = fitted["DANCE_W_1"]
    pos = motion.positions()
    assert np.mean(pos[:, J["right_wrist"], 1] > pos[:, J["left_wrist"], 1]) > 0.6
    _, world = fk_numpy(motion.skeleton, motion.rotations, motion.root_positions)
    head, chest = world[:, J["head"]] @ [0, 0, 1], world[:, J["spine3"]] @ [0, 0, 1]
    yaw = np.degrees(np.arctan2(head[:, 0], head[:, 2]) - np.arctan2(chest[:, 0], chest[:, 2]))
    yaw = (yaw + 180) % 360 - 180
    assert np.median(yaw) > 10.0  # left is +X: a positive turn about +Y looks left


@pytest.mark.data
def test_fit_rotations_are_smooth(fitted: dict) -> None:
    motion, _ = fitted["DANCE_C_2"]
    q = Rotation.from_rotvec(motion.rotations[:, :BODY_JOINTS].reshape(-1, 3)).as_quat().reshape(-1, BODY_JOINTS, 4)
    step = np.degrees(2 * np.arccos(np.clip(np.abs((q[1:] * q[:-1]).sum(-1)), 0, 1)))
    # Joints turn less than 20 degrees per frame (500 deg/s) in 99% of frames; the rare larger steps
    # are arms folded almost flat, where the elbow's hinge axis is ill-defined.
    assert np.percentile(step, 99) < 20.0


def test_music_and_motion_cover_the_same_seconds() -> None:
    """A feature that equals song time lands on each motion frame's song time (offset + t / fps)."""
    song_s = 30.0
    feats = np.repeat((np.arange(int(song_s * 10)) / 10.0)[:, None], 15, axis=1)
    offset = 6.24
    t = np.arange(200)
    music = music_at_frames(feats, 10.0, offset + t / 25.0)
    np.testing.assert_allclose(music[:, 0], offset + t / 25.0, atol=1e-5)


def _pair(seed: int, frames: int = 400, style: str = "waltz") -> PairedSequence:
    """A synthetic pair whose music says which pair and which frame it is (columns 0 and 1)."""
    rng = np.random.default_rng(seed)
    tt = np.arange(frames) / 25
    rot = 0.2 * np.sin(tt[:, None, None] * rng.uniform(0.5, 3, (1, 55, 3)))
    rot[:, 25:] = 0.0
    m = Motion(rot, np.stack([0.1 * np.sin(tt), 0.95 + 0 * tt, 0.1 * np.cos(tt)], -1), 25.0)
    music = np.zeros((frames, 15), np.float32)
    music[:, 0], music[:, 1] = seed, np.arange(frames)
    return PairedSequence(f"S{seed}", style, encode(m), encode(m.mirrored()), music,
                          m.positions()[:, :BODY_JOINTS].astype(np.float32), m.skeleton.offsets, 0.0, 0.0)


def test_windows_keep_music_with_motion_and_balance_clusters() -> None:
    pairs = [_pair(s, style=st) for s, st in ((0, "waltz"), (1, "rumba"), (2, "waltz"))]
    layout = FeatureLayout(55, 5)
    norm = Normalizer.fit([p.motion for p in pairs], binary=layout.contacts)
    sampler = WindowSampler(pairs, norm, ["rumba", "waltz"], layout, window=100, stride=3, clusters=4)
    assert len(sampler.cluster_sizes) == 4
    totals = np.bincount(sampler.labels, weights=sampler.weights)  # each cluster gets equal weight
    np.testing.assert_allclose(totals, 0.25, atol=1e-9)
    b = sampler.batch(np.random.default_rng(0), 16, input_noise=0.0, target_noise=0.0)
    mirrored_seen = 0
    for k in range(16):
        pair = pairs[int(b.music[k, 0, 0])]
        start = int(b.music[k, 0, 1])
        np.testing.assert_array_equal(b.music[k, :, 1], np.arange(start, start + 100))
        plain = norm.normalize(pair.motion[start : start + 100])
        mirror = norm.normalize(pair.mirrored[start : start + 100])
        assert np.allclose(b.target[k], plain, atol=1e-5) or np.allclose(b.target[k], mirror, atol=1e-5)
        mirrored_seen += not np.allclose(b.target[k], plain, atol=1e-5)
        assert b.style[k] == ["rumba", "waltz"].index(pair.style)
    assert 0 < mirrored_seen < 16  # the mirror augmentation is used, with the same music


def test_mirror_twice_gives_the_same_features() -> None:
    m = Motion(np.random.default_rng(3).normal(0, 0.3, (50, 55, 3)), np.zeros((50, 3)) + [0, 0.9, 0], 25.0)
    np.testing.assert_allclose(encode(m.mirrored().mirrored()), encode(m), atol=1e-6)


def test_split_is_by_song_and_fixed() -> None:
    from dancenet_core.data.split import load_split

    split = load_split()
    train, test = set(split["train"]), set(split["test"])
    assert train
    assert test
    assert not train & test
    assert not (train | test) & set(split["excluded"])  # the time-compressed tango T_5 is in neither
    assert set(split["validation"]) < train  # validation songs are training songs DanceNet leaves out
    styles = {s.split("_")[1] for s in test}
    assert styles == {"C", "R", "T", "W"}  # every shipped style is held out somewhere
