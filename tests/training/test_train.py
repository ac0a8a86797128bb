"""Warm starts: a trained DanceNet carried into a model with more mixture components, a new style or
residual outputs starts where the source was (or, for residual outputs, as 'copy the last frame')."""

from __future__ import annotations

import numpy as np
import torch

from dancenet_core.model.dancenet import DanceNet, DanceNetConfig
from dancenet_core.training.dancenet import warm_start, with_own_predictions


def _net(mixtures: int, styles: list[str], residual: bool, seed: int) -> DanceNet:
    torch.manual_seed(seed)
    cfg = DanceNetConfig(motion_dim=12, continuous_dim=10, styles=styles, mixtures=mixtures,
                         motion_channels=32, residual_channels=16, skip_channels=32, music_window=40,
                         music_overlap=10, residual_output=residual)
    return DanceNet(cfg).eval()


def _inputs() -> tuple[torch.Tensor, torch.Tensor]:
    rng = np.random.default_rng(0)
    return torch.tensor(rng.normal(size=(2, 60, 12)), dtype=torch.float32), \
        torch.tensor(rng.normal(size=(2, 60, 15)), dtype=torch.float32)


def test_more_components_and_a_new_style_start_from_the_source() -> None:
    src = _net(1, ["a", "c"], residual=False, seed=0)
    dst = _net(4, ["a", "b", "c"], residual=False, seed=1)
    warm_start(dst, src)
    x, music = _inputs()
    with torch.no_grad():
        a = src.split(src(x, music, torch.tensor([0, 1])))
        b = dst.split(dst(x, music, torch.tensor([0, 2])))  # style c is index 1 in src, 2 in dst
    torch.testing.assert_close(b[1][..., 0, :], a[1][..., 0, :])  # component 0's means
    torch.testing.assert_close(b[2][..., 3, :], a[2][..., 0, :])  # every component's sigmas
    torch.testing.assert_close(b[3], a[3])  # contacts
    assert torch.allclose(b[0], torch.zeros_like(b[0]))  # equal weights
    assert not torch.allclose(b[1][..., 1, :], b[1][..., 0, :])  # the others nudged apart


def test_residual_outputs_start_by_copying_the_last_frame_and_same_heads_copy_exactly() -> None:
    src = _net(1, ["a"], residual=False, seed=0)
    dst = _net(2, ["a"], residual=True, seed=1)
    warm_start(dst, src)
    x, music = _inputs()
    with torch.no_grad():
        mu = dst.split(dst(x, music, torch.tensor([0, 0])))[1]
    torch.testing.assert_close(mu[..., 0, :], x[:, :-1, :10])
    same = _net(2, ["a"], residual=True, seed=2)
    warm_start(same, dst)
    with torch.no_grad():
        torch.testing.assert_close(same(x, music, torch.tensor([0, 0])), dst(x, music, torch.tensor([0, 0])))


def test_own_predictions_replace_the_chosen_share_of_frames_after_the_first() -> None:
    """Scheduled sampling's inputs: share 0 keeps the real frames, share 1 replaces every frame but the first
    with the model's own draws (contacts 0/1, constant channels kept at zero)."""
    net = _net(2, ["a"], residual=False, seed=0)
    net.modelled[4] = False
    x, music = _inputs()
    x[..., 4] = 0.0
    style = torch.tensor([0, 0])
    torch.testing.assert_close(with_own_predictions(net, x, music, style, 0.0), x)
    own = with_own_predictions(net, x, music, style, 1.0)
    torch.testing.assert_close(own[:, 0], x[:, 0])
    modelled = [c for c in range(10) if c != 4]
    assert not torch.isclose(own[:, 1:, modelled], x[:, 1:, modelled]).any()
    assert set(own[:, 1:, 10:].unique().tolist()) <= {0.0, 1.0}
    assert (own[..., 4] == 0).all()
    half = with_own_predictions(net, x, music, style, 0.5)
    replaced = ~torch.isclose(half[:, 1:, 0], x[:, 1:, 0])
    assert 0.3 < replaced.float().mean() < 0.7
