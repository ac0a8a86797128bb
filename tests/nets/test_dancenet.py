"""DanceNet: shapes, causality, the mixture loss, and cached generation equal to the full forward pass."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dancenet_core.nets.dancenet import DanceNet, DanceNetConfig, dancenet_loss, mixture_nll, naive_run
from dancenet_core.runtime.sampler import CachedSampler, Sampling, music_conditioning


def _model(mixtures: int = 2, residual_output: bool = False, input_skip: bool = False) -> DanceNet:
    torch.manual_seed(0)
    cfg = DanceNetConfig(motion_dim=12, continuous_dim=10, styles=["a", "b"], mixtures=mixtures,
                         motion_channels=32, residual_channels=16, skip_channels=32, music_window=40,
                         music_overlap=10, residual_output=residual_output, input_skip=input_skip)
    m = DanceNet(cfg)
    if input_skip:  # trained weights, not the zeros it starts from
        torch.nn.init.normal_(m.input_skip.weight, std=0.3)
        torch.nn.init.normal_(m.input_skip.bias, std=0.3)
    m.eval()
    return m


def test_receptive_field_matches_the_paper() -> None:
    cfg = DanceNetConfig(motion_dim=10, continuous_dim=8)
    assert cfg.dilations[:6] == [1, 2, 4, 8, 16, 1]
    assert len(cfg.dilations) == 20
    assert cfg.receptive_field == 125


def test_forward_is_causal() -> None:
    m = _model()
    x = torch.randn(1, 60, 12)
    music = torch.randn(1, 60, 15)
    style = torch.tensor([1])
    cond = m.conditioning(music, style)
    out = m.forward_frames(x, cond)
    x2 = x.clone()
    x2[:, 40:] += 1.0
    out2 = m.forward_frames(x2, cond)
    assert torch.allclose(out[:, :40], out2[:, :40])
    assert not torch.allclose(out[:, 40:], out2[:, 40:])


def test_mixture_nll_of_a_standard_normal() -> None:
    d = 4
    target = torch.zeros(1, d)
    nll = mixture_nll(torch.zeros(1, 1), torch.zeros(1, 1, d), torch.zeros(1, 1, d), target, torch.ones(d))
    assert float(nll) == pytest.approx(0.5 * np.log(2 * np.pi), abs=1e-6)


def test_loss_is_finite_and_trains() -> None:
    m = _model()
    m.train()
    x = torch.randn(4, 50, 12)
    x[..., 10:] = (x[..., 10:] > 0).float()
    music = torch.randn(4, 50, 15)
    style = torch.tensor([0, 1, 0, 1])
    opt = torch.optim.Adam(m.parameters(), 1e-3)
    first = None
    for _ in range(30):
        loss, parts = dancenet_loss(m, m(x, music, style), x[:, 1:])
        opt.zero_grad()
        loss.backward()
        opt.step()
        first = first if first is not None else float(loss.detach())
    assert np.isfinite(float(loss))
    assert float(loss) < first


@pytest.mark.parametrize(("residual_output", "input_skip"), [(False, False), (True, False), (False, True)])
def test_cached_generation_equals_full_forward(residual_output: bool, input_skip: bool) -> None:
    """Teacher-force the cached sampler with known frames: its outputs equal one full forward pass."""
    m = _model(residual_output=residual_output, input_skip=input_skip)
    m.modelled[3] = False  # a constant channel: never modelled, so no change is added to it either
    rng = np.random.default_rng(0)
    t = 200
    frames = rng.normal(size=(2, t, 12)).astype(np.float32)
    music = rng.normal(size=(t, 15)).astype(np.float32)
    cond = music_conditioning(m, music, style=1)
    _, cached = CachedSampler(m).run(frames[:, 0], cond, teacher=frames, record_outputs=True)
    with torch.no_grad():
        cond_t = torch.tensor(cond).T.unsqueeze(0).expand(2, -1, -1)
        full = m.forward_frames(torch.tensor(frames[:, :-1]), cond_t[..., 1:]).numpy()
    np.testing.assert_allclose(cached[:, 1:], full, atol=1e-5)
    naive = naive_run(m, frames[:, 0], cond, frames)
    np.testing.assert_allclose(naive[:, 1:], full, atol=1e-5)


def test_sampling_is_seeded_and_uses_temperature() -> None:
    m = _model()
    cond = music_conditioning(m, np.zeros((120, 15), np.float32), style=0)
    first = np.zeros((3, 12), np.float32)
    a, _ = CachedSampler(m).run(first, cond, Sampling(0.5, np.random.default_rng(7)))
    b, _ = CachedSampler(m).run(first, cond, Sampling(0.5, np.random.default_rng(7)))
    c, _ = CachedSampler(m).run(first, cond, Sampling(0.5, np.random.default_rng(8)))
    cold, _ = CachedSampler(m).run(first, cond, Sampling(0.0, np.random.default_rng(8)))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.isfinite(a).all()
    assert set(np.unique(a[..., 10:])) <= {0.0, 1.0}
    # Three takes in one batch differ from each other; at temperature 0 they are identical.
    assert not np.array_equal(a[0], a[1])
    assert np.array_equal(cold[0], cold[1])


def test_music_conditioning_any_length() -> None:
    m = _model()
    for t in (5, 40, 41, 333):
        c = music_conditioning(m, np.zeros((t, 15), np.float32), style=0)
        assert c.shape == (t, m.cfg.music_code + m.cfg.style_dim)
        assert np.isfinite(c).all()


def test_sampling_commits_to_one_component_drawn_by_its_weight() -> None:
    """Two components with means -1 and +1 and weights 0.25 / 0.75: each frame is drawn near one of the means
    (never their average, whatever the temperature within it), about a quarter of them near -1."""
    m = _model(mixtures=2)
    k, d = 2, m.cfg.continuous_dim
    with torch.no_grad():
        last = m.decoder[3]
        last.weight.zero_()
        bias = torch.zeros_like(last.bias)
        bias[:k] = torch.log(torch.tensor([0.25, 0.75]))
        bias[k : k + d] = -1.0
        bias[k + d : k + 2 * d] = 1.0
        bias[k + 2 * d : k + 4 * d] = float(np.log(0.05))  # sigma 0.05 (softplus floor far below)
        last.bias.copy_(bias)
    cond = music_conditioning(m, np.zeros((400, 15), np.float32), style=0)
    frames, _ = CachedSampler(m).run(np.zeros((4, 12), np.float32), cond, Sampling(1.0, np.random.default_rng(0)))
    x = frames[:, 1:, :d]
    assert np.abs(np.abs(x) - 1).max() < 0.35  # near a mean, never near 0
    # All channels of a frame come from the same component.
    assert (np.sign(x) == np.sign(x[..., :1])).all()
    assert abs((x[..., 0] < 0).mean() - 0.25) < 0.05
    # Temperature scales the spread within the chosen component only.
    cold, _ = CachedSampler(m).run(np.zeros((4, 12), np.float32), cond, Sampling(0.1, np.random.default_rng(0)))
    assert np.abs(np.abs(cold[:, 1:, :d]) - 1).max() < 0.035


def test_a_residual_output_adds_the_change_to_the_last_frame() -> None:
    """With residual outputs, zero change and a tiny sigma at temperature 1 replay the first frame exactly
    where it is modelled; the same network without them predicts its own means instead."""
    for residual in (True, False):
        m = _model(mixtures=1, residual_output=residual)
        with torch.no_grad():
            last = m.decoder[3]
            last.weight.zero_()
            last.bias.zero_()
            last.bias[1 + 10 : 1 + 20] = -20.0  # log sigma far below the floor: sigma = 0.03
        cond = music_conditioning(m, np.zeros((50, 15), np.float32), style=0)
        first = np.linspace(-1, 1, 12, dtype=np.float32)[None]
        frames, _ = CachedSampler(m).run(first, cond, Sampling(0.0, np.random.default_rng(0)))
        expected = first[0, :10] if residual else np.zeros(10)
        np.testing.assert_allclose(frames[0, -1, :10], expected, atol=1e-6)


def test_an_input_skip_starts_at_zero() -> None:
    """A new input-skip path adds nothing, so a warm start from a network without one keeps its outputs."""
    plain = _model()
    skip = DanceNet(DanceNetConfig(**(plain.cfg.to_dict() | {"input_skip": True})))
    missing = skip.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert sorted(missing) == ["input_skip.bias", "input_skip.weight"]
    skip.eval()
    x, cond = torch.randn(2, 30, 12), torch.randn(2, 35, 30)
    with torch.no_grad():
        torch.testing.assert_close(skip.forward_frames(x, cond), plain.forward_frames(x, cond))
