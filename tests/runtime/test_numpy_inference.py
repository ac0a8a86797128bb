"""Generation without torch: each network's numpy forward equals its torch forward (random and real inputs, any
DanceNet configuration), the shipped runtime files are exports of the shipped checkpoints, a whole dance is the
torch path's dance, and a Generate Dance never imports torch."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from dancenet_core import generate
from dancenet_core.engines import dancenet as dancenet_engine
from dancenet_core.engines import styles
from dancenet_core.errors import DanceNetError
from dancenet_core.music.features import FPS as MUSIC_FPS
from dancenet_core.music.features import N_FEATURES, MusicAnalysis, analyze_music, music_at_frames
from dancenet_core.music.style import N_INPUTS, classifier_input
from dancenet_core.nets.bundle import DanceNetBundle
from dancenet_core.nets.dancenet import DanceNet
from dancenet_core.nets.export import bundle_to_runtime, fixer_to_runtime, style_to_runtime
from dancenet_core.nets.footfix import FootFixer
from dancenet_core.nets.style_torch import StyleModel, build_net
from dancenet_core.representation import Normalizer, encode
from dancenet_core.request import DanceRequest
from dancenet_core.runtime.config import DanceNetConfig
from dancenet_core.runtime.numpy_nets import toe_heights
from dancenet_core.runtime.sampler import CachedSampler, Sampling, music_conditioning
from dancenet_core.runtime.weights import RuntimeBundle, RuntimeFootFixer, RuntimeStyleModel
from dancenet_core.skeleton import DEFAULT_SKELETON

REPO = Path(__file__).resolve().parents[2]
SONG = REPO / "examples" / "example_song.ogg"
NETS = 1e-5  # numpy forward against torch forward
# A whole dance against the torch path's, at the default temperature, as joint positions (metres; rotation vectors
# near pi may flip). Sampling turns any difference in the music code into centimetres of dance (a float32
# rounding of it moved a take of the example song by 3.8 cm at temperature 0.1, and by metres at 1.0), so both
# paths compute the code in float64 and round it once: the same code, the same sampled frames, and only the
# foot clean-up's float32 differences left (3e-7 m measured).
DANCE = 1e-4


def _randomise_batchnorm(module: torch.nn.Module, seed: int) -> None:
    """Trained-looking BatchNorm statistics, so folding them into the convs is really tested."""
    g = torch.Generator().manual_seed(seed)
    for m in module.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            n = m.num_features
            m.running_mean.copy_(torch.randn(n, generator=g))
            m.running_var.copy_(torch.rand(n, generator=g) + 0.2)
            m.weight.data.copy_(torch.randn(n, generator=g))
            m.bias.data.copy_(torch.randn(n, generator=g))


def _torch_conditioning(model: DanceNet, music: np.ndarray, style: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return model.conditioning(torch.from_numpy(music), torch.from_numpy(style)).transpose(1, 2).numpy()


@pytest.fixture(scope="module")
def shipped() -> tuple[DanceNetBundle, StyleModel, FootFixer]:
    return DanceNetBundle.load(), StyleModel.load(), FootFixer.load()


@pytest.fixture(scope="module")
def analysis() -> MusicAnalysis:
    return analyze_music(SONG)


@pytest.mark.parametrize("options", [
    {"mixtures": 3, "input_skip": True},
    {"residual_output": True},
    {"music_encoder": "frame"},
    {"music_dim": 80, "music_features": "mel", "mixtures": 2},
])
def test_any_dancenet_config_runs_from_arrays(options: dict, tmp_path: Path) -> None:
    """Conditioning (random music) to 1e-5, and the cached sampler from the saved arrays gives the torch
    model's dance, with kept frames (`prefix`) too."""
    torch.manual_seed(0)
    cfg = DanceNetConfig(motion_dim=12, continuous_dim=10, styles=["a", "b"], motion_channels=32,
                         residual_channels=16, skip_channels=32, music_window=40, music_overlap=10, **options)
    model = DanceNet(cfg)
    _randomise_batchnorm(model, 1)
    for p in (model.input_skip.parameters() if model.input_skip is not None else []):
        torch.nn.init.normal_(p, std=0.3)  # trained weights, not the zeros it starts from
    model.eval()
    rng = np.random.default_rng(0)
    music = rng.normal(size=(3, 40, cfg.music_dim)).astype(np.float32)
    style = np.array([0, 1, 1])
    np.testing.assert_allclose(model.to_numpy().conditioning(music, style),
                               _torch_conditioning(model, music, style), atol=NETS, rtol=0)

    norm = Normalizer(np.zeros(12, np.float32), np.ones(12, np.float32), np.zeros(12, bool))
    bundle = DanceNetBundle(model, norm, DEFAULT_SKELETON, {"a": rng.normal(size=(2, 12))})
    bundle_to_runtime(bundle).save(tmp_path / "dancenet.npz")
    runtime = RuntimeBundle.load(tmp_path / "dancenet.npz")
    song = rng.normal(size=(130, cfg.music_dim)).astype(np.float32)
    conds = [music_conditioning(m, song, 1) for m in (model, runtime.model)]
    np.testing.assert_allclose(conds[1], conds[0], atol=NETS, rtol=0)
    prefix = rng.normal(size=(2, 30, 12)).astype(np.float32)
    dances = [CachedSampler(m).run(prefix[:, 0], conds[0], Sampling(0.5, np.random.default_rng(3)), prefix=prefix)[0]
              for m in (model, runtime.model)]
    np.testing.assert_array_equal(dances[1], dances[0])
    np.testing.assert_array_equal(dances[1][:, :30], prefix)


def test_shipped_runtime_files_are_exports_of_the_checkpoints(shipped: tuple) -> None:
    """What generation loads is what training made: re-export the shipped checkpoints and compare (a stale
    .npz after new weights fails here: run `dancenet weights export`)."""
    bundle, style, fixer = shipped
    runtime = RuntimeBundle.load()
    assert runtime.model.cfg == bundle.model.cfg
    fresh = bundle_to_runtime(bundle)
    for got, want in ((runtime.model.state, fresh.model.state), (RuntimeStyleModel.load().net.state,
                      style_to_runtime(style).net.state), (RuntimeFootFixer.load().net.state,
                      fixer_to_runtime(fixer).net.state)):
        assert got.keys() == want.keys()
        for k in want:
            np.testing.assert_array_equal(got[k], want[k], err_msg=k)
    for s in bundle.styles:
        np.testing.assert_array_equal(runtime.start_frames[s], bundle.start_frames[s])
    np.testing.assert_array_equal(runtime.normalizer.std, bundle.normalizer.std)


def test_shipped_music_encoder_on_random_and_real_music(shipped: tuple, analysis: MusicAnalysis) -> None:
    bundle = shipped[0]
    model, runtime = bundle.model, RuntimeBundle.load().model
    cfg = model.cfg
    rng = np.random.default_rng(1)
    music = rng.normal(size=(4, cfg.music_window, cfg.music_dim)).astype(np.float32)
    style = rng.integers(len(cfg.styles), size=4)
    np.testing.assert_allclose(runtime.conditioning(music, style), _torch_conditioning(model, music, style),
                               atol=NETS, rtol=0)
    n = int(analysis.duration_s * cfg.fps)
    song = music_at_frames(analysis.features, MUSIC_FPS, np.arange(n) / cfg.fps)
    for s in range(len(cfg.styles)):  # computed in float64 and rounded once: the very same code (see DANCE)
        np.testing.assert_array_equal(music_conditioning(runtime, song, s), music_conditioning(model, song, s))


@pytest.mark.parametrize("arch", ["conv", "baseline"])
@pytest.mark.parametrize("inputs", [N_INPUTS, N_FEATURES])  # with metre and tempo, and weights from before them
def test_style_networks_on_random_input(arch: str, inputs: int) -> None:
    """Windows one by one, and a song's overlapping windows at once (an odd last start, and a song shorter
    than a window), against torch on each window."""
    torch.manual_seed(2)
    model = StyleModel(build_net(arch, 4, inputs=inputs), arch, ["a", "b", "c", "d"], {"inputs": inputs})
    _randomise_batchnorm(model.net, 3)
    model.eval_mode()
    net = style_to_runtime(model).net
    rng = np.random.default_rng(2)
    x = rng.normal(size=(5, 300, inputs)).astype(np.float32)
    np.testing.assert_allclose(net(x), model.logits(x), atol=NETS, rtol=0)
    song = rng.normal(size=(457, inputs)).astype(np.float32)
    for starts, length in ((np.array([0, 50, 100, 157]), 300), (np.array([0]), 120)):
        windows = np.stack([song[s : s + length] for s in starts])
        np.testing.assert_allclose(net.windows(song[: max(starts) + length], starts, length), model.logits(windows),
                                   atol=NETS, rtol=0)


def test_shipped_style_classifier_on_real_music(shipped: tuple, analysis: MusicAnalysis) -> None:
    torch_model, runtime = shipped[1], RuntimeStyleModel.load()
    x = classifier_input(analysis)[None, : torch_model.window]
    with torch.no_grad():
        want = torch_model.net(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(runtime.net(x), want, atol=NETS, rtol=0)
    a, b = runtime.classify(analysis), torch_model.classify(analysis)
    assert a.styles == b.styles
    np.testing.assert_allclose(a.window_probabilities, b.window_probabilities, atol=NETS, rtol=0)


def test_foot_model_and_floor_guard(shipped: tuple, analysis: MusicAnalysis) -> None:
    """Random frames and a real dance (the shipped model's, to the example song): the increment, the toe heights
    the floor guard reads and the whole clean-up equal torch's."""
    fixer, runtime = shipped[2], RuntimeFootFixer.load()
    ch = fixer.ch
    rng = np.random.default_rng(4)
    random = fixer.norm.denormalize(rng.normal(size=(300, len(fixer.norm.mean))).astype(np.float32))
    dance = generate.generate_dance(DanceRequest(SONG, seed=5, footfix=False, end_s=20.0))
    real = np.concatenate([encode(m) for m in dance.motions])
    for feats in (random, real):
        x = fixer.norm.normalize(feats)
        with torch.no_grad():
            inc = fixer.model(torch.from_numpy(x[None, :, ch.inputs]))[0].numpy()
            heights = fixer.kin(torch.from_numpy(x[None, :, ch.lower]))[0, ..., 1].numpy()
        np.testing.assert_allclose(runtime.net(x[:, ch.inputs]), inc, atol=NETS, rtol=0)
        lower = x[:, ch.lower] * fixer.norm.std[ch.lower] + fixer.norm.mean[ch.lower]
        np.testing.assert_allclose(toe_heights(lower, fixer.skeleton), heights, atol=NETS, rtol=0)
        np.testing.assert_allclose(runtime(feats), fixer(feats), atol=NETS, rtol=0)


@pytest.fixture
def torch_path(monkeypatch: pytest.MonkeyPatch, shipped: tuple) -> None:
    """generate_dance as before this runtime: the torch networks of the shipped checkpoints."""
    bundle, style, fixer = shipped
    monkeypatch.setattr(dancenet_engine, "load_bundle", lambda path=None: bundle)
    monkeypatch.setattr(styles, "load_style_model", lambda path=None: style)
    monkeypatch.setattr(dancenet_engine, "foot_fixer", lambda: fixer)


def _dances(**kwargs: object) -> generate.GenerationResult:
    return generate.generate_dance(DanceRequest(SONG, seed=11, takes=2, **kwargs))


def test_generate_dance_equals_the_torch_path(request: pytest.FixtureRequest) -> None:
    """The whole Generate Dance (style chosen by the classifier, music encoder, sampler, foot clean-up), and the
    same kept dance continued from its 10th second, against the torch networks: same seed, same dance, at the
    default temperature."""
    ours = _dances()
    ours_continued = _dances(continue_from=ours.motions[0], at_s=10.0)
    request.getfixturevalue("torch_path")
    theirs = _dances()
    theirs_continued = _dances(continue_from=ours.motions[0], at_s=10.0)
    for a, b in ((ours, theirs), (ours_continued, theirs_continued)):
        assert a.style == b.style
        for s in a.style_probabilities:
            assert a.style_probabilities[s] == pytest.approx(b.style_probabilities[s], abs=NETS)
        for ma, mb, ca, cb in zip(a.motions, b.motions, a.contacts, b.contacts, strict=True):
            np.testing.assert_allclose(ma.positions(), mb.positions(), atol=DANCE, rtol=0)
            np.testing.assert_array_equal(ca, cb)


def test_generation_imports_no_torch(tmp_path: Path) -> None:
    """A Generate Dance (and a continued one) in a fresh interpreter, with the modules the add-on uses: torch is
    never imported."""
    code = (
        "import sys\n"
        "from dancenet_core import kinematics, motion, bvh\n"
        "from dancenet_core.shaping import rootmotion\n"
        "from dancenet_core.generate import available_styles, generate_dance\n"
        "from dancenet_core.request import DanceRequest\n"
        f"r = generate_dance(DanceRequest({str(SONG)!r}, seed=1, end_s=12.0))\n"
        f"generate_dance(DanceRequest({str(SONG)!r}, seed=2, end_s=12.0, continue_from=r.motions[0], at_s=4.0))\n"
        "assert available_styles()\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'torch')[:3])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO,
                         env=os.environ | {"PYTHONPATH": str(REPO)}, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "[]"


def test_runtime_files_never_unpickle(tmp_path: Path) -> None:
    """A runtime file holding a pickled object, random bytes or another kind of file is refused in one line."""
    np.savez(tmp_path / "pickled.npz", meta=np.array(['{"format": "dancenet-runtime-1"}']),
             evil=np.array([{"a": 1}], dtype=object))
    (tmp_path / "random.npz").write_bytes(np.random.default_rng(0).bytes(1000))
    RuntimeFootFixer.load().save(tmp_path / "footfix.npz")
    for name, message in (("pickled", "cannot read"), ("random", "cannot read"), ("footfix", "not a DanceNet")):
        with pytest.raises(DanceNetError, match=message) as e:
            RuntimeBundle.load(tmp_path / f"{name}.npz")
        assert "\n" not in str(e.value)


def test_a_foot_model_for_other_channels_is_refused_in_one_line(tmp_path: Path) -> None:
    """A foot model file whose network writes other channels (here the root's travel channels as well as the
    feet's) is a one-line error at loading, not a broadcast error in the middle of a dance."""
    fixer = RuntimeFootFixer.load()
    w, b = fixer.net.state["net.4.weight"], fixer.net.state["net.4.bias"]
    extra = len(fixer.ch.lower) - len(fixer.ch.corrected)  # the travel channels it must not write
    state = fixer.net.state | {"net.4.weight": np.concatenate([w, w[:extra]]), "net.4.bias": np.r_[b, b[:extra]]}
    fixer.net.state = state
    fixer.save(tmp_path / "old.npz")
    with pytest.raises(DanceNetError, match="for other channels") as e:
        RuntimeFootFixer.load(tmp_path / "old.npz")
    assert "\n" not in str(e.value)
