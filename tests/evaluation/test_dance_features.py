"""AIST++ kinetic and geometric features on bodies whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from dancenet_core.evaluation.dance_features import (
    GEOMETRIC_FEATURES,
    GEOMETRIC_INDEX,
    SCALES,
    dance_features,
    geometric_features,
    kinetic_features,
    smpl24_positions,
)
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX

RIGHT_WRIST, RIGHT_ELBOW, RIGHT_HAND, RIGHT_ANKLE = 21, 19, 23, 8


def _still(frames: int) -> np.ndarray:
    """Our rest pose (a T-pose, pelvis 0.9 m up) as SMPL's 24 joints, held for `frames` frames."""
    rest = DEFAULT_SKELETON.rest_positions() + np.array([0.0, 0.9, 0.0])
    return np.repeat(smpl24_positions(rest[None]), frames, axis=0)


def test_smpl24_takes_body_joints_and_middle_knuckles_as_hands() -> None:
    p55 = np.random.default_rng(0).standard_normal((5, 55, 3))
    p24 = smpl24_positions(p55)
    assert p24.shape == (5, 24, 3)
    assert np.array_equal(p24[:, :BODY_JOINTS], p55[:, :BODY_JOINTS])
    assert np.array_equal(p24[:, 22], p55[:, JOINT_INDEX["left_middle1"]])
    assert np.array_equal(p24[:, 23], p55[:, JOINT_INDEX["right_middle1"]])
    with pytest.raises(ValueError):
        smpl24_positions(p55[:, :BODY_JOINTS])


def test_kinetic_features_of_a_still_body_are_zero() -> None:
    k = kinetic_features(_still(50), 25.0)
    assert k.shape == (72,)
    assert np.all(k == 0)


@pytest.mark.parametrize("fps", [25.0, 60.0])
def test_kinetic_energy_of_a_joint_at_constant_velocity(fps: float) -> None:
    v = np.array([0.6, -0.3, 0.8])  # m/s
    p = _still(int(3 * fps))
    p[:, RIGHT_WRIST] += np.arange(len(p))[:, None] / fps * v
    k = kinetic_features(p, fps).reshape(24, 3)
    assert k[RIGHT_WRIST] == pytest.approx([v[0] ** 2 + v[2] ** 2, v[1] ** 2, 0.0], abs=1e-5)
    assert np.all(np.delete(k, RIGHT_WRIST, axis=0) == 0)


def test_energy_expenditure_of_constant_acceleration_is_its_magnitude() -> None:
    fps, g = 30.0, 9.81
    p = _still(60)
    t = np.arange(60) / fps
    p[:, 0, 1] -= 0.5 * g * t**2  # the root falls freely
    k = kinetic_features(p, fps).reshape(24, 3)
    assert k[0, 2] == pytest.approx(g, rel=1e-5)
    assert k[0, 0] == 0.0
    assert k[0, 1] > 0


def test_geometric_features_count_and_a_still_body_never_moves() -> None:
    assert len(GEOMETRIC_FEATURES) == 32
    g = geometric_features(_still(20), 25.0)
    assert g.shape == (32,)
    assert set(np.unique(g)) <= {0.0, 1.0}
    moving = [i for i, s in enumerate(GEOMETRIC_FEATURES) if s[0] in ("move", "nmove", "fast")]
    assert len(moving) == 12
    assert np.all(g[moving] == 0)
    assert g[GEOMETRIC_INDEX["rwrist_above_neck"]] == 0
    assert g[GEOMETRIC_INDEX["rankle_raised"]] == 0


def test_hand_above_the_head_flips_its_feature_on_one_side_only() -> None:
    p = _still(10)
    shoulder = p[0, 17]
    p[:, RIGHT_ELBOW] = shoulder + [0, 0.26, 0]
    p[:, RIGHT_WRIST] = shoulder + [0, 0.51, 0]
    p[:, RIGHT_HAND] = shoulder + [0, 0.6, 0]
    g = geometric_features(p, 25.0)
    assert g[GEOMETRIC_INDEX["rwrist_above_neck"]] == 1.0
    assert g[GEOMETRIC_INDEX["lwrist_above_neck"]] == 0.0


def test_raised_foot_and_fast_root_at_any_frame_rate() -> None:
    for fps in (25.0, 60.0):
        p = _still(int(2 * fps))
        p[:, RIGHT_ANKLE, 1] += 1.2 * SCALES["hl"] + 0.05  # above the lowest joint by more than 1.2 humeri
        assert geometric_features(p, fps)[GEOMETRIC_INDEX["rankle_raised"]] == 1.0
        # AIST++ thresholds twice the true speed at 2.3 humerus lengths per second: 0.29 m/s true.
        for speed, expected in ((0.25, 0.0), (0.35, 1.0)):
            walk = _still(int(2 * fps)) + (np.arange(int(2 * fps)) / fps * speed)[:, None, None] * [1, 0, 0]
            assert geometric_features(walk, fps)[GEOMETRIC_INDEX["root_fast"]] == expected


def test_dance_features_crop_to_bailando_s_20_seconds() -> None:
    rng = np.random.default_rng(1)
    p55 = np.repeat(DEFAULT_SKELETON.rest_positions()[None], 750, axis=0)
    p55 += rng.standard_normal((750, 1, 3)).cumsum(axis=0) * 0.01  # the whole body wanders
    k, g = dance_features(p55, 25.0)
    first = smpl24_positions(p55[:500])
    assert np.array_equal(k, kinetic_features(first, 25.0))
    assert np.array_equal(g, geometric_features(first, 25.0))
    assert not np.array_equal(k, kinetic_features(smpl24_positions(p55), 25.0))
