"""The comparison's models (DanceNet, its ablations, the paper's baselines) and its segmenting."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancenet_core.comparison import segments
from dancenet_core.model.variants import VARIANTS, build_model, sample_normalized
from dancenet_core.representation import FeatureLayout

LAYOUT = FeatureLayout(55, 5)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_every_model_learns_a_window_and_dances(variant: str) -> None:
    """Each model fits one fixed batch (its loss falls by half) and then dances any length of music."""
    torch.manual_seed(0)
    model = build_model(variant, LAYOUT.size, LAYOUT.continuous.stop, ["a", "b"], window=64)
    rng = np.random.default_rng(0)
    t = np.linspace(0, 4 * np.pi, 48)
    motion = np.sin(t[None, :, None] + rng.uniform(0, 6, (2, 1, LAYOUT.size))).astype(np.float32)
    motion[..., LAYOUT.contacts] = (motion[..., LAYOUT.contacts] > 0).astype(np.float32)
    music = rng.normal(size=(2, 48, model.cfg.music_dim)).astype(np.float32)
    x, m, s = torch.tensor(motion), torch.tensor(music), torch.tensor([0, 1])
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    losses = []
    for _ in range(40):
        loss, _ = model.loss(model(x, m, s), x[:, 1:], m[:, 1:])
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < losses[0] - 0.5 * abs(losses[0]), (variant, losses[0], losses[-1])

    model.eval()
    song = rng.normal(size=(150, model.cfg.music_dim)).astype(np.float32)
    a = sample_normalized(model, song, 1, motion[0, 0], 0.1, np.random.default_rng(3))
    b = sample_normalized(model, song, 1, motion[0, 0], 0.1, np.random.default_rng(3))
    assert a.shape == (150, LAYOUT.size) and np.isfinite(a).all()
    assert np.array_equal(a, b)  # same seed, same dance
    assert set(np.unique(a[1:, LAYOUT.contacts])) <= {0.0, 1.0}


def test_mse_models_dance_their_mean_whatever_the_temperature() -> None:
    model = build_model("dancenet_mse", LAYOUT.size, LAYOUT.continuous.stop, ["a"], window=64).eval()
    song = np.random.default_rng(0).normal(size=(30, 15)).astype(np.float32)
    first = np.zeros(LAYOUT.size, np.float32)
    hot = sample_normalized(model, song, 0, first, 5.0, np.random.default_rng(1))
    cold = sample_normalized(model, song, 0, first, 0.0, np.random.default_rng(2))
    np.testing.assert_array_equal(hot, cold)


def test_segments_are_whole_and_do_not_overlap() -> None:
    pos = np.arange(26 * 10 * 3 * 2, dtype=float).reshape(-1, 2, 3)  # 260 frames
    segs = segments(pos, fps=25.0, seconds=4.0)
    assert [len(s) for s in segs] == [100, 100]  # the 60-frame tail is dropped
    np.testing.assert_array_equal(segs[1][0], pos[100])
