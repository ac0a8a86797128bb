"""Warm starts (a trained DanceNet carried into a model with more mixture components, a new style or
residual outputs starts where the source was, or, for residual outputs, as 'copy the last frame'), and the
training levers against timid dances: own rollouts, the travel loss, windows drawn on the device, the pack."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from dancenet_core.data.build import PairedSequence
from dancenet_core.data.pack import load_pack, save_pack
from dancenet_core.data.windows import WindowSampler
from dancenet_core.errors import DanceNetError
from dancenet_core.nets.bundle import DanceNetBundle
from dancenet_core.nets.dancenet import DanceNet, DanceNetConfig
from dancenet_core.representation import FeatureLayout, Normalizer
from dancenet_core.skeleton import DEFAULT_SKELETON
from dancenet_core.training.blend import blend
from dancenet_core.training.dancenet import (
    hide_history,
    own_mask,
    prime_rmsprop,
    travel_loss,
    warm_start,
    with_own_predictions,
)
from dancenet_core.training.tensor_windows import TensorWindows


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


def test_chained_passes_converge_to_a_free_run_of_the_own_stretches() -> None:
    """With own stretches of 3 frames and 3 passes, the window's first stretch was drawn from the frames
    before it as they stand in the result: the model ran free there. Later stretches also depend on earlier
    ones (the receptive field is longer than a stretch), so more passes bring them closer to a free run."""
    net = _net(1, ["a"], residual=False, seed=0)
    x, music = _inputs()
    style = torch.tensor([0, 0])

    def gap(passes: int) -> tuple[float, float]:
        """Largest gap between own frames and the means drawn from the result: first stretch, all."""
        torch.manual_seed(3)
        mixed = with_own_predictions(net, x, music, style, 0.5, passes=passes, stretch=3, temperature=0.0)
        own = ~torch.isclose(mixed[:, 1:, 0], x[:, 1:, 0])
        with torch.no_grad():
            mean = net.split(net(mixed, music, style))[1][..., 0, :]
        err = (mean - mixed[:, 1:, :10]).abs().amax(-1)
        first = own.int().cumsum(1) <= 3
        return err[own & first].max().item(), err[own].max().item()

    gaps = {p: gap(p) for p in (1, 3, 6)}
    assert gaps[3][0] < 1e-5 < gaps[1][0]
    assert gaps[6][1] < 0.2 * gaps[3][1] < gaps[1][1]


def test_own_stretches_cover_the_share_asked_for() -> None:
    for share in (0.3, 0.5):
        mask = own_mask((64, 400), share, 10, torch.device("cpu"))
        assert abs(mask.float().mean().item() - share) < 0.05
        runs = torch.diff(mask[0].int()).abs().sum().item()  # own stretches come whole, not as single frames
        assert runs <= 2 * 400 / 10 * share + 2


def test_hidden_history_hides_whole_frames_in_stretches() -> None:
    frames = torch.randn(8, 200, 5) + 3.0
    hidden = hide_history(frames, 0.25, 12)
    gone = (hidden == 0).all(-1)
    assert ((hidden == frames).all(-1) | gone).all()  # a frame is kept whole or hidden whole
    assert abs(gone.float().mean().item() - 0.25) < 0.05
    assert torch.diff(gone[0].int()).abs().sum().item() <= 2 * 200 / 12 * 0.25 + 2


def test_travel_loss_is_zero_on_the_dancers_path_and_grows_with_a_timid_one() -> None:
    """Expected root steps equal to the dancer's: no loss; the same steps at half length: a loss near the
    4-s window's (1 - 0.5)^2 = 0.25 of the displacement's spread."""
    net = _net(1, ["a"], residual=False, seed=0)
    k, d = net.cfg.mixtures, net.cfg.continuous_dim
    rng = np.random.default_rng(0)
    target = torch.tensor(rng.normal(size=(4, 150, 12)), dtype=torch.float32)
    target[..., 0] = 1.0  # steady forward-ish steps so the path has extent
    out = torch.zeros(4, 150, net.cfg.mixtures * (1 + 2 * d) + 2)
    out[..., k : k + d] = target[..., :d]
    mean, std = torch.zeros(3), torch.full((3,), 0.02)
    assert travel_loss(net, out, target, mean, std, [25, 100]).item() < 1e-6
    timid = out.clone()
    timid[..., k : k + d] *= 0.5
    loss = travel_loss(net, timid, target, mean, std, [25, 100]).item()
    assert 0.1 < loss < 0.5


def test_device_windows_are_the_samplers_windows(tmp_path: Path) -> None:
    """The tensor batch holds real windows of the sequences (or their mirror images) with their music and
    style, at the noise asked for: the same data as the numpy batch."""
    layout = FeatureLayout(3, 1)
    rng = np.random.default_rng(0)
    pairs = [PairedSequence(f"S{i}", "waltz" if i else "tango", rng.normal(size=(90, layout.size)).astype(np.float32),
                            rng.normal(size=(90, layout.size)).astype(np.float32),
                            rng.normal(size=(90, 15)).astype(np.float32), np.zeros((90, 22, 3), np.float32),
                            np.zeros((3, 3)), 1.0, 2.0) for i in range(2)]
    norm = Normalizer.fit([p.motion for p in pairs], binary=layout.contacts)
    sampler = WindowSampler(pairs, norm, ["tango", "waltz"], layout, window=30, stride=5, clusters=2)
    b = TensorWindows(sampler, torch.device("cpu")).batch(16, input_noise=0.0, target_noise=0.0)
    assert b.motion.shape == (16, 30, layout.size) and b.music.shape == (16, 30, 15)
    for w in range(16):
        p = pairs[int(b.style[w])]  # style index = sequence here
        start = int(np.argmin(np.abs(p.music[:, 0] - b.music[w, 0, 0].item())))
        sources = [norm.normalize(p.motion), norm.normalize(p.mirrored)]
        assert any(np.allclose(b.motion[w].numpy(), src[start : start + 30], atol=1e-5) for src in sources)
        np.testing.assert_allclose(b.music[w].numpy(), p.music[start : start + 30])
    pack = tmp_path / "pack.npz"
    save_pack(pairs, pack)
    back = load_pack(pack)
    assert [p.seq for p in back] == ["S0", "S1"] and back[1].style == "waltz"
    np.testing.assert_allclose(back[0].motion, pairs[0].motion, rtol=1e-3, atol=1e-3)


def test_a_primed_rmsprop_takes_an_ordinary_first_step() -> None:
    """From an empty history RMSprop moves every weight by 10x the learning rate on its first step (what
    jolted warm starts); primed with the mean squared gradient, the first step is about the rate."""
    x, music = _inputs()

    def first_step(prime: bool) -> float:
        net = _net(1, ["a"], residual=False, seed=0).train()
        opt = torch.optim.RMSprop(net.parameters(), lr=1e-4)

        def batch_loss() -> tuple[torch.Tensor, dict]:
            noisy = x + 0.04 * torch.randn_like(x)
            return net.loss(net(noisy, music, torch.tensor([0, 0])), x[:, 1:], music[:, 1:])

        if prime:
            prime_rmsprop(opt, net, batch_loss)
        before = [p.detach().clone() for p in net.parameters()]
        opt.zero_grad()
        batch_loss()[0].backward()
        opt.step()
        moved = torch.cat([(p.detach() - b).abs().flatten() for p, b in zip(net.parameters(), before, strict=True)])
        return moved[moved > 0].median().item() / 1e-4

    assert first_step(prime=False) > 9.0
    assert first_step(prime=True) < 3.0


def test_a_blend_lies_between_its_ends_and_refuses_other_lineages() -> None:
    """alpha 0 and 1 give the two networks' outputs; 0.5 gives each weight's midpoint; a network of other
    sizes is refused in one line."""
    start, end = _net(1, ["a"], residual=False, seed=0), _net(1, ["a"], residual=False, seed=1)
    norm = Normalizer(np.zeros(12), np.ones(12), np.zeros(12, bool))
    bundles = [DanceNetBundle(n, norm, DEFAULT_SKELETON, {}, {}) for n in (start, end)]
    x, music = _inputs()
    style = torch.tensor([0, 0])
    with torch.no_grad():
        for alpha, ref in ((0.0, start), (1.0, end)):
            torch.testing.assert_close(blend(*bundles, alpha).model(x, music, style), ref(x, music, style))
    half = blend(*bundles, 0.5).model.state_dict()
    torch.testing.assert_close(half["decoder.3.weight"],
                               (start.state_dict()["decoder.3.weight"] + end.state_dict()["decoder.3.weight"]) / 2)
    other = DanceNetBundle(_net(2, ["a"], residual=False, seed=2), norm, DEFAULT_SKELETON, {}, {})
    with pytest.raises(DanceNetError, match="different network settings"):
        blend(bundles[0], other, 0.5)


@pytest.mark.parametrize("command", [["train", "dancenet"], ["validate"]])
def test_training_commands_start_without_audio_libraries(command: list[str]) -> None:
    """The GPU machine that trains from a pack has neither madmom nor soundfile: the training and validation
    commands must not import them (a module-level soundfile import once stopped a whole GPU loan)."""
    import subprocess
    import sys

    code = ("import sys; sys.modules['soundfile'] = sys.modules['madmom'] = None\n"
            "from dancenet_core.cli import main\n"
            f"try:\n    main({command + ['--help']!r})\nexcept SystemExit as e:\n    sys.exit(e.code)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
