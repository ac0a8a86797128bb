"""The contact lock (two-bone IK on predicted contacts) and the floor pass from predicted contacts, on made-up
dances whose feet slide and hover by known amounts."""

from __future__ import annotations

import numpy as np

from dancenet_core.motion import Motion
from dancenet_core.shaping.floor import contact_floor, floor_shift, toe_ends
from dancenet_core.shaping.footlock import GROUND_M, STILL_MPS, contact_runs, hold_offsets, lock_feet, planted_feet
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_INDEX, TOE_ENDS

FPS = 25.0


def _gliding(frames: int = 100, lift: float = 0.0, speed: float = 0.5) -> Motion:
    """A dancer with bent knees gliding forward at `speed` m/s, swaying a little, its toes `lift` above the floor."""
    t = np.arange(frames) / FPS
    rot = np.zeros((frames, 55, 3))
    for side in ("left", "right"):
        rot[:, JOINT_INDEX[f"{side}_hip"], 0] = -0.3
        rot[:, JOINT_INDEX[f"{side}_knee"], 0] = 0.5
        rot[:, JOINT_INDEX[f"{side}_ankle"], 0] = -0.2
    rot[:, JOINT_INDEX["spine1"], 2] = 0.1 * np.sin(2 * np.pi * t)
    root = np.stack([0.02 * np.sin(np.pi * t), np.full(frames, 0.9), speed * t], -1)
    m = Motion(rot, root, FPS, DEFAULT_SKELETON)
    low = m.end_effectors()[:, list(TOE_ENDS), 1].min()
    m.root_positions[:, 1] += lift - low
    return m


def test_holds_skip_flicker_and_shift_the_swing_smoothly() -> None:
    planted = np.zeros(80, bool)
    planted[10:20] = planted[40:50] = True
    planted[70] = True  # one frame: flicker
    assert contact_runs(planted, FPS) == [(10, 20), (40, 50)]
    toe = np.stack([0.5 * np.arange(80) / FPS, np.zeros(80)], -1)  # gliding at 0.5 m/s
    shift = hold_offsets(toe, planted, FPS)
    held = toe + shift
    assert np.ptp(held[10:20, 0]) < 1e-12 and np.ptp(held[40:50, 0]) < 1e-12  # still while planted
    speed = np.abs(np.diff(held[:, 0])) * FPS
    assert speed.max() < 0.5 + 0.5 * 1.6  # the swing between holds and the easing add at most ~0.8 m/s
    assert (shift[:2] == 0).all() and (shift[-5:] == 0).all()  # nothing far from the holds


def test_a_planted_foot_stays_put_and_only_the_legs_move() -> None:
    m = _gliding()
    contacts = np.zeros((m.num_frames, 2))
    contacts[30:50, 0] = 1  # the left foot planted for 0.8 s while the body glides 0.4 m
    locked = lock_feet(m, contacts)
    before, after = m.end_effectors()[:, list(TOE_ENDS)], locked.end_effectors()[:, list(TOE_ENDS)]
    held = after[30:50, 0]
    assert np.linalg.norm(held[:, [0, 2]] - held[:, [0, 2]].mean(0), axis=-1).max() < 0.01  # was 0.2 m either way
    assert np.abs(held[:, 1] - before[30:50, 0, 1]).max() < 0.02  # the toe keeps its height
    np.testing.assert_allclose(after[:, 1], before[:, 1], atol=1e-9)  # the other foot is untouched
    np.testing.assert_allclose(after[:15, 0], before[:15, 0], atol=1e-9)  # so is this one away from the hold
    changed = np.abs(locked.rotations - m.rotations).max(axis=(0, 2)) > 1e-9
    legs = {JOINT_INDEX[n] for n in ("left_hip", "left_knee", "left_ankle")}
    assert set(np.flatnonzero(changed)) <= legs
    np.testing.assert_array_equal(locked.root_positions, m.root_positions)
    # The foot lies as it did: the ankle's world turn is kept.
    from dancenet_core.kinematics import fk_numpy

    wr0, wr1 = fk_numpy(m.skeleton, m.rotations, m.root_positions)[1], fk_numpy(
        m.skeleton, locked.rotations, locked.root_positions)[1]
    a = JOINT_INDEX["left_ankle"]
    np.testing.assert_allclose(wr1[:, a], wr0[:, a], atol=1e-6)


def test_a_foot_left_still_on_the_floor_counts_as_planted() -> None:
    m = _gliding(lift=0.0, speed=1.0)  # the toes on the floor, gliding at 1 m/s: too fast to count
    assert STILL_MPS < 1.0
    none = np.zeros((m.num_frames, 2))
    assert not planted_feet(m, none).any()
    m.root_positions[40:60, [0, 2]] = m.root_positions[40, [0, 2]]  # the body stops for 0.8 s
    planted = planted_feet(m, none)
    assert planted[41:60].all() and not planted[:40].any() and not planted[61:].any()
    predicted = none.copy()
    predicted[5:10, 1] = 1
    assert planted_feet(m, predicted)[5:10, 1].all()  # the model's contacts always count
    assert not planted_feet(_gliding(lift=GROUND_M + 0.01, speed=0.0), none).any()  # still, but above the floor


def test_the_floor_pass_stands_a_hovering_dance_on_its_planted_feet() -> None:
    m = _gliding(lift=0.06)
    contacts = np.zeros((m.num_frames, 2))
    contacts[::2, 0] = 1
    shift = floor_shift(m, contacts)
    np.testing.assert_allclose(shift, -0.06, atol=1e-6)
    np.testing.assert_allclose(contact_floor(toe_ends(m)[:, :, 1], contacts, FPS), 0.06, atol=1e-6)
    np.testing.assert_allclose(toe_ends(m), m.end_effectors()[:, list(TOE_ENDS)], atol=1e-12)
    sunk = _gliding(lift=-0.04)
    placed = sunk.root_positions[:, 1] + floor_shift(sunk, contacts)
    lowest = Motion(sunk.rotations, sunk.root_positions * [1, 0, 1] + placed[:, None] * [0, 1, 0], FPS,
                    sunk.skeleton).end_effectors()[:, list(TOE_ENDS), 1].min(axis=1)
    assert lowest.min() > -1e-6 and lowest.max() < 1e-3


def test_the_shipped_model_dances_on_the_floor_with_planted_feet() -> None:
    """Generate Dance with the shipped weights, with and without the foot clean-up: both stand on the floor in
    nearly every 2-s window; the clean-up holds the predicted contacts still (the toes slide far less there) and
    moves only the legs."""
    from pathlib import Path

    from dancenet_core.evaluation.metrics import floor_reach
    from dancenet_core.generate import generate_dance
    from dancenet_core.request import DanceRequest

    song = Path(__file__).resolve().parents[1] / "examples" / "example_song.ogg"
    dances = {f: generate_dance(DanceRequest(song, seed=3, end_s=20.0, style="cha-cha", footfix=f))
              for f in (True, False)}
    for f, d in dances.items():
        toes = toe_ends(d.motions[0])
        assert floor_reach(toes[:, :, 1].min(axis=1), d.motions[0].fps) >= 0.9, f
    cleaned, raw = (dances[f].motions[0] for f in (True, False))
    planted = dances[True].contacts[0] > 0.5
    np.testing.assert_array_equal(planted, dances[False].contacts[0] > 0.5)  # same draws, same contacts

    def planted_speed(m: Motion) -> float:
        step = np.linalg.norm(np.diff(toe_ends(m)[:, :, [0, 2]], axis=0), axis=-1) * m.fps
        both = planted[1:] & planted[:-1]
        return float(step[both].mean())

    assert planted_speed(cleaned) < 0.3 * planted_speed(raw)
    legs = {JOINT_INDEX[f"{s}_{j}"] for s in ("left", "right") for j in ("hip", "knee", "ankle")}
    changed = np.abs(cleaned.rotations - raw.rotations).max(axis=(0, 2)) > 1e-6
    assert set(np.flatnonzero(changed)) <= legs
    np.testing.assert_allclose(cleaned.root_positions[:, [0, 2]], raw.root_positions[:, [0, 2]], atol=1e-9)
