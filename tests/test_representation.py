"""The paper's motion representation: encode/decode round trips, foot contact, normalisation."""

from __future__ import annotations

import numpy as np
import pytest

from dancenet_core.data.dance_with_melody import P, load_positions, read_manifest
from dancenet_core.data.fit import fit_sequence, initial_pose, performer_skeleton
from dancenet_core.motion import Motion
from dancenet_core.representation import FeatureLayout, Normalizer, decode, encode, start_pose
from dancenet_core.skeleton import MIRROR_INDEX, TOE_ENDS


def _synthetic(frames: int = 3000, fps: float = 25.0, seed: int = 0) -> Motion:
    """A dancer that spins (yaw passes many multiples of 2 pi), travels and bobs."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / fps
    rot = 0.3 * np.sin(t[:, None, None] * rng.uniform(0.5, 3, (1, 55, 3)) + rng.uniform(0, 6, (1, 55, 3)))
    rot[:, 0] = [0.1, 1.0, 0.0] * np.stack([np.sin(t), t, t], -1)  # tilt and a steady spin
    root = np.stack([np.cumsum(0.01 * np.cos(0.3 * t)), 0.95 + 0.05 * np.sin(4 * t),
                     np.cumsum(0.01 * np.sin(0.2 * t))], -1)  # fmt: skip
    return Motion(rot, root, fps)


def _round_trip_error(m: Motion) -> float:
    feats = encode(m)
    size = FeatureLayout.for_skeleton(m.skeleton).size
    assert feats.dtype == np.float32
    assert feats.shape == (m.num_frames, size)
    yaw, xz = start_pose(m)
    back = decode(feats, m.fps, m.skeleton, start_yaw=yaw, start_xz=xz)
    return float(np.abs(back.positions() - m.positions()).max())


def test_round_trip_synthetic_spinning_two_minutes() -> None:
    assert _round_trip_error(_synthetic()) < 1e-3


@pytest.fixture(scope="module")
def real_two_minutes(shared_data) -> Motion:
    """Two minutes (3000 frames at 25 fps) of real dance: two rumbas back to back, skeleton fitted."""
    seqs = {s.seq: s for s in read_manifest(shared_data)}
    pos = np.concatenate([load_positions(seqs["DANCE_R_4"]), load_positions(seqs["DANCE_R_7"])])[:3000]
    skeleton, _ = performer_skeleton(pos)
    return Motion(initial_pose(skeleton, pos), pos[:, P["pelvis"]], 25.0, skeleton)


def test_round_trip_real_motion_within_1mm(real_two_minutes: Motion) -> None:
    assert real_two_minutes.duration >= 120.0
    assert _round_trip_error(real_two_minutes) < 1e-3


def test_foot_contact_on_real_planted_feet(shared_data) -> None:
    """Frames where the raw toe marker is still on the floor are flagged; clearly moving feet are not."""
    seqs = {s.seq: s for s in read_manifest(shared_data)}
    raw = load_positions(seqs["DANCE_R_4"])[:600]
    n = len(raw)
    fitted, _ = fit_sequence(raw, 25.0, steps=120)
    contacts = encode(fitted)[:, FeatureLayout.for_skeleton(fitted.skeleton).contacts]
    for side, toe in enumerate((P["l_toe"], P["r_toe"])):
        p = raw[:, toe]
        speed = np.zeros(n)
        speed[1:-1] = np.linalg.norm(p[2:, [0, 2]] - p[:-2, [0, 2]], axis=-1) * 25 / 2
        floor = np.percentile(raw[:, [P["l_toe"], P["r_toe"]], 1].min(1), 5)
        height = p[:, 1] - floor
        planted = (speed < 0.1) & (height < 0.03)
        moving = (speed > 1.0) | (height > 0.15)
        assert planted.sum() > 50
        assert moving.sum() > 50
        assert contacts[planted, side].mean() > 0.9
        assert contacts[moving, side].mean() < 0.1


def test_contacts_follow_toe_end_height_and_speed() -> None:
    toes = np.zeros((10, 2, 3))
    toes[:, 1, 1] = 0.3  # right foot in the air
    toes[5:, 0, 0] = np.arange(5) * 0.1  # left foot slides at 2.5 m/s from frame 5
    m = _synthetic(10)
    from dancenet_core.representation import foot_contacts

    c = foot_contacts(toes, m.fps, floor=0.0)
    assert c[:4, 0].all()
    assert not c[6:, 0].any()
    assert not c[:, 1].any()


def test_normalizer_handles_constant_channels() -> None:
    m = _synthetic(500)
    m.rotations[:, 25:] = 0.0  # fingers at rest: constant channels
    feats = encode(m)
    layout = FeatureLayout.for_skeleton(m.skeleton)
    norm = Normalizer.fit(feats, binary=layout.contacts)
    z = norm.normalize(feats)
    assert np.isfinite(z).all()
    finger_channels = slice(layout.rotations.start + 3 * 24, layout.rotations.stop)
    assert norm.constant[finger_channels].all()
    assert not norm.constant[layout.root].any()
    np.testing.assert_allclose(norm.denormalize(z), feats, atol=1e-5)
    np.testing.assert_array_equal(z[:, layout.contacts], feats[:, layout.contacts])


def test_mirror_twice_is_identity_and_mirrors_positions() -> None:
    m = _synthetic(50)
    np.testing.assert_allclose(m.mirrored().mirrored().rotations, m.rotations, atol=1e-12)
    mirrored = m.mirrored().positions()
    np.testing.assert_allclose(mirrored, m.positions()[:, list(MIRROR_INDEX)] * [-1, 1, 1], atol=1e-9)
    assert TOE_ENDS == (0, 1)


def test_resample_keeps_duration_and_pose() -> None:
    m = _synthetic(250, fps=25.0)
    r = m.resampled(60.0)
    assert r.num_frames == 600
    np.testing.assert_allclose(r.positions()[::12], m.positions()[::5], atol=1e-9)


def _path_length(root: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=-1).sum())


def test_generation_post_processing_keeps_the_travel() -> None:
    """What happens to a dance's features after sampling (denormalise, output smoothing, decode) keeps at
    least 97% of the path the features describe: nothing on the way shrinks the root's deltas."""
    from types import SimpleNamespace

    from dancenet_core.engines.dancenet import finish_frames

    m = _synthetic()
    feats = encode(m)
    layout = FeatureLayout.for_skeleton(m.skeleton)
    norm = Normalizer.fit(feats, binary=layout.contacts)
    bundle = SimpleNamespace(normalizer=norm, model=SimpleNamespace(cfg=SimpleNamespace(
        continuous_dim=layout.continuous.stop)))
    back = decode(finish_frames(bundle, norm.normalize(feats)), m.fps, m.skeleton)
    assert _path_length(back.root_positions) >= 0.97 * _path_length(m.root_positions)
    extent = np.linalg.norm(back.root_positions[-1, [0, 2]] - back.root_positions[0, [0, 2]])
    assert extent >= 0.97 * np.linalg.norm(m.root_positions[-1, [0, 2]] - m.root_positions[0, [0, 2]])
