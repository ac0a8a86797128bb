"""Motion style classifier: learns two synthetic 'styles' it can tell apart, and the shipped model
classifies a real held-out dance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancenet_core.evaluation.motion_style import MotionStyleModel, motion_input
from dancenet_core.motion import Motion
from dancenet_core.skeleton import BODY_JOINTS, DEFAULT_SKELETON, JOINT_INDEX, Skeleton
from dancenet_core.training.motion_style import Dance, score_dances, train_motion_style_net

WRISTS = (20, 21)


def _synthetic(style_hz: float, seconds: float, fps: float, rng: np.random.Generator) -> np.ndarray:
    """A body [T, 22, 3] bouncing and swinging its arms at style_hz, facing a random way at a random place."""
    t = np.arange(int(seconds * fps)) / fps
    phase = rng.uniform(0, 2 * np.pi)
    p = np.repeat(DEFAULT_SKELETON.rest_positions()[None, :BODY_JOINTS] + [0.0, 0.9, 0.0], len(t), axis=0)
    p[:, :, 1] += rng.uniform(0.03, 0.06) * np.sin(2 * np.pi * style_hz * t + phase)[:, None]
    for w in WRISTS:
        p[:, w, 2] += rng.uniform(0.1, 0.2) * np.sin(2 * np.pi * style_hz * t + phase + 1.0)
    yaw = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    p = p @ rot.T + [rng.uniform(-3, 3), 0.0, rng.uniform(-3, 3)]
    return p + rng.normal(0, 0.005, p.shape)


def test_input_ignores_where_which_way_and_how_high_the_dance_is() -> None:
    rng = np.random.default_rng(0)
    p = _synthetic(1.0, 4.0, 25.0, rng)
    yaw = 2.0
    rot = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    moved = p @ rot.T + [5.0, 0.3, -7.0]  # feet 30 cm above the floor, too
    assert np.allclose(motion_input(p, 25.0), motion_input(moved, 25.0), atol=1e-4)


def test_input_ignores_the_dancer_s_size_and_proportions() -> None:
    """The same dance (same joint rotations) by a dancer with 15% longer legs and 10% shorter arms, whose
    root path is longer by the legs' ratio, gives the network the same input."""
    rng = np.random.default_rng(2)
    t = 100
    rotations = np.zeros((t, 55, 3))
    phases = rng.uniform(0, 6, (1, BODY_JOINTS, 3))
    rotations[:, :BODY_JOINTS] = 0.3 * np.sin(np.linspace(0, 6, t)[:, None, None] + phases)
    root = np.stack([np.linspace(0, 2, t), 0.9 + 0.03 * np.sin(np.linspace(0, 20, t)), np.zeros(t)], axis=1)
    offsets = DEFAULT_SKELETON.offsets.copy()
    legs = [JOINT_INDEX[n] for n in ("left_knee", "left_ankle", "right_knee", "right_ankle")]
    offsets[legs] *= 1.15
    offsets[[JOINT_INDEX[n] for n in ("left_elbow", "left_wrist", "right_elbow", "right_wrist")]] *= 0.9
    a = Motion(rotations, root, 25.0).positions()
    b = Motion(rotations, root * 1.15, 25.0, Skeleton(offsets)).positions()
    assert np.abs(a - b).max() > 0.1
    assert np.allclose(motion_input(a[:, :BODY_JOINTS], 25.0), motion_input(b[:, :BODY_JOINTS], 25.0), atol=1e-4)


def test_tiny_model_tells_two_synthetic_styles_apart(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    styles = {"slow": 1.0, "quick": 2.2}
    train = [Dance(f"{s}{i}", s, _synthetic(hz, 12.0, 25.0, rng)) for s, hz in styles.items() for i in range(6)]
    model = train_motion_style_net(train, steps=80, batch=16, lr=3e-3, segment_s=4.0, seed=0,
                        config={"channels": 16, "hidden": 16, "dropout": 0.0}, log=lambda _: None)  # fmt: skip
    assert model.styles == ("quick", "slow")  # read from the data, sorted
    path = tmp_path / "m.pt"
    model.save(path)
    loaded = MotionStyleModel.load(path)
    for style, hz in styles.items():
        for _ in range(4):  # new dances, captured at another frame rate
            p = _synthetic(hz, 4.0, 50.0, rng)
            probs = loaded.classify(p, 50.0)
            assert probs.shape == (2,)
            assert probs.sum() == pytest.approx(1.0, abs=1e-5)
            assert loaded.styles[int(probs.argmax())] == style
            assert np.allclose(probs, model.classify(p, 50.0), atol=1e-6)
            assert loaded.embed(p, 50.0).shape == (loaded.embedding_size,) == (32,)
    held_out = [Dance(f"t{s}", s, _synthetic(hz, 12.0, 25.0, rng)) for s, hz in styles.items()]
    result = score_dances(loaded, held_out)
    assert result["segment_accuracy"] == 1.0
    assert result["dance_accuracy"] == 1.0


@pytest.mark.data  # fits a whole capture sequence
def test_shipped_model_classifies_a_real_held_out_dance(shared_data: Path, tmp_path: Path) -> None:
    from dancenet_core.data.build import build_sequence
    from dancenet_core.data.dance_with_melody import read_manifest
    from dancenet_core.data.split import load_split
    from dancenet_core.representation import decode

    model = MotionStyleModel.load()
    split = load_split()
    seqs = {s.seq: s for s in read_manifest(shared_data)}
    assert set(model.styles) == {seqs[s].style for s in split["train"]}
    assert "DANCE_W_3" in split["test"]
    dance = build_sequence(seqs["DANCE_W_3"], tmp_path)  # a held-out waltz, fitted here (one sequence only)
    motion = decode(dance.motion[:250], 25.0)  # 10 s, as a generated dance arrives: 55 joints from features
    probs = model.classify(motion.positions(), 25.0)
    assert probs.sum() == pytest.approx(1.0, abs=1e-5)
    assert model.styles[int(probs.argmax())] == dance.style
    assert model.embed(motion.positions(), 25.0).shape == (model.embedding_size,)
    per_segment = model.classify_segments(dance.positions, 25.0)
    assert np.mean([model.styles[i] == dance.style for i in per_segment.argmax(axis=1)]) > 0.8
