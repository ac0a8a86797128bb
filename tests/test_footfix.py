"""Foot Constraint Model: its inputs and outputs, training on simulated sliding, and the shipped weights."""

from __future__ import annotations

import numpy as np
import torch

from dancenet_core.footfix import (
    WEIGHTS,
    FootChannels,
    FootConstraintModel,
    FootFixer,
    LstmBaseline,
    simulate_sliding,
    train_model,
)
from dancenet_core.motion import Motion
from dancenet_core.representation import FeatureLayout, Normalizer, encode
from dancenet_core.skeleton import LOWER_BODY

LAYOUT = FeatureLayout(55, 5)


def test_channels_cover_root_legs_toes_and_contacts() -> None:
    ch = FootChannels.for_layout(LAYOUT)
    assert len(ch.lower) == 6 + 3 * (len(LOWER_BODY) - 1) and len(ch.toes) == 6 and len(ch.contacts) == 2
    assert set(ch.lower) & set(ch.toes) == set() and ch.contacts.tolist() == [183, 184]
    assert ch.toes.min() >= LAYOUT.end_effectors.start and ch.toes.max() < LAYOUT.end_effectors.start + 6


def test_model_is_three_dilated_convs_that_see_the_future() -> None:
    ch = FootChannels.for_layout(LAYOUT)
    m = FootConstraintModel(len(ch.inputs), len(ch.lower))
    convs = [c for c in m.net if isinstance(c, torch.nn.Conv1d)]
    assert [c.dilation[0] for c in convs] == [1, 3, 9] and all(c.kernel_size[0] == 3 for c in convs)
    x = torch.randn(1, 80, len(ch.inputs))
    y = m(x)
    x2 = x.clone()
    x2[:, 60] += 1.0
    assert y.shape == (1, 80, len(ch.lower)) and not torch.allclose(m(x2)[:, 50], y[:, 50])


def _dances(n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        t = np.arange(300) / 25
        rot = 0.3 * np.sin(t[:, None, None] * rng.uniform(0.5, 2, (1, 55, 3)) * 2 * np.pi)
        rot[:, 25:] = 0
        root = np.stack([0.3 * np.sin(t), 0.95 + 0 * t, 0.3 * np.cos(0.5 * t)], -1)
        out.append(encode(Motion(rot, root, 25.0)))
    return out


def test_training_on_simulated_sliding_beats_doing_nothing() -> None:
    train, test = _dances(4, 0), _dances(2, 1)
    norm = Normalizer.fit(train, binary=LAYOUT.contacts)
    ch = FootChannels.for_layout(LAYOUT)
    train, test = [norm.normalize(x) for x in train], [norm.normalize(x) for x in test]
    noisy = simulate_sliding(np.stack(test)[:, :200], ch, np.random.default_rng(0))
    assert not np.allclose(noisy[..., ch.lower], np.stack(test)[:, :200, ch.lower])
    np.testing.assert_array_equal(noisy[..., ch.contacts], np.stack(test)[:, :200, ch.contacts])
    n_in, n_out = len(ch.inputs), len(ch.lower)
    for model in (FootConstraintModel(n_in, n_out, 32), LstmBaseline(n_in, n_out, 32)):
        res = train_model(model, train, test, ch, steps=60, window=100, batch=8)
        assert res["test_mse"] < res["test_mse_without_model"]


def test_shipped_fixer_loads_and_keeps_upper_body() -> None:
    fixer = FootFixer.load(WEIGHTS)
    feats = _dances(1, 2)[0]
    fixed = fixer(feats)
    ch = FootChannels.for_layout(LAYOUT)
    others = np.setdiff1d(np.arange(LAYOUT.size), ch.lower)
    np.testing.assert_allclose(fixed[:, others], feats[:, others], atol=1e-5)
    assert np.isfinite(fixed).all() and not np.allclose(fixed[:, ch.lower], feats[:, ch.lower])
