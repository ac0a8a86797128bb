"""The numba kernels' numpy twins (dancenet_core/jit.py) give the same numbers bit for bit, so a Generate Dance
clicked before the add-on's kernels are compiled dances what it dances after: the music networks' loop, the
beat decode, the sampler, and a whole dance from a song, same seed, same frames and beats."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancenet_core import jit
from dancenet_core.engines.dancenet import load_bundle
from dancenet_core.music import madmom_dbn, madmom_nets
from dancenet_core.music.features import N_FEATURES, _tracker
from dancenet_core.runtime import sampler
from dancenet_core.runtime.numpy_nets import NumpyDanceNet
from dancenet_core.runtime.sampler import CachedSampler, Sampling, music_conditioning

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def twins(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every kernel call runs its twin, compiled or not."""
    monkeypatch.setattr(jit, "pick", lambda kernel, twin: twin)


@pytest.mark.parametrize("lstm", [True, False])
def test_scan_twin(lstm: bool) -> None:
    """Random recurrences of madmom's two layer kinds, both directions, padded units, large inputs (exp's
    clamps and overflow to inf included)."""
    rng = np.random.default_rng(0)
    n_a, n_t, n_b, n_h, stride = 2, 200, 2, 13, 16
    gates, n_c = (4 if lstm else 1), 4
    pre = 30.0 * rng.standard_normal((n_a, n_t, n_b, gates * n_h))
    rec = np.zeros((n_c, n_h, gates, stride))
    rec[..., :n_h] = rng.standard_normal((n_c, n_h, gates, n_h))
    peep = np.zeros((n_c, 3, stride))
    if lstm:
        peep[..., :n_h] = rng.standard_normal((n_c, 3, n_h))
    args = (pre, rng.standard_normal((n_c, gates * n_h)), rec.reshape(n_c, n_h, -1), peep,
            rng.standard_normal((n_c, n_h)), rng.standard_normal((n_c, n_h)), np.arange(n_c) % 2 == 1, lstm)
    compiled, twin = np.zeros((n_c // 2, n_t, 2, n_h)), np.ones((n_c // 2, n_t, 2, n_h))
    madmom_nets._scan(*args, compiled)
    with np.errstate(over="ignore"):
        madmom_nets._scan_numpy(*args, twin)
    np.testing.assert_array_equal(twin, compiled)


@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning")  # madmom's log densities of the zeros
def test_viterbi_twin(monkeypatch: pytest.MonkeyPatch) -> None:
    """Coarse activations (many paths score alike, so the order of comparison decides) with exact zeros
    (states no path may pass through): the same path and log probability as the compiled decode."""
    rng = np.random.default_rng(0)
    act = rng.choice(np.array([0.0, 0.125, 0.25], np.float32), size=(1500, 2))
    act[::50, 0] = 0.5
    act[::200, 1] = 0.5
    for hmm in _tracker().hmms:
        path, log_prob = hmm.viterbi(act)
        monkeypatch.setattr(jit, "pick", lambda kernel, twin: twin)
        twin_path, twin_log_prob = hmm.viterbi(act)
        monkeypatch.undo()
        assert twin_log_prob == log_prob
        np.testing.assert_array_equal(twin_path, path)
    assert madmom_dbn._viterbi.signatures  # the compiled decode did run


@pytest.mark.parametrize("temperature", [1.0, 0.0])
def test_sampler_twin(temperature: float, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two takes of the shipped model on made-up music: the same frames and raw outputs."""
    model = load_bundle().model
    bundle = load_bundle()
    cond = music_conditioning(model, np.random.default_rng(1).standard_normal((60, N_FEATURES), np.float32), 1)
    first = bundle.normalizer.normalize(bundle.start_frames[bundle.styles[0]][:2])

    def run() -> tuple[np.ndarray, np.ndarray | None]:
        return CachedSampler(model).run(first, cond, Sampling(temperature, np.random.default_rng(5)),
                                        record_outputs=True)

    frames, outputs = run()
    assert sampler._generate.signatures
    monkeypatch.setattr(jit, "pick", lambda kernel, twin: twin)
    twin_frames, twin_outputs = run()
    np.testing.assert_array_equal(twin_frames, frames)
    np.testing.assert_array_equal(twin_outputs, outputs)


def test_a_runaway_sigma_is_held_at_the_draw_limit_by_kernel_and_twin(monkeypatch: pytest.MonkeyPatch) -> None:
    """A model whose sigma head runs away (here every log-sigma pushed up by 40) draws values held within
    DRAW_LIMIT standard deviations, finite, the same in the compiled sampler and its twin."""
    bundle = load_bundle()
    model = bundle.model
    k, cont = model.cfg.mixtures, model.cfg.continuous_dim
    state = dict(model.state)
    bias = np.array(state["decoder.3.bias"], copy=True)
    bias[k + k * cont : k + 2 * k * cont] += 40.0
    state["decoder.3.bias"] = bias
    wild = NumpyDanceNet(model.cfg, state)
    cond = music_conditioning(wild, np.random.default_rng(1).standard_normal((30, N_FEATURES), np.float32), 1)
    first = bundle.normalizer.normalize(bundle.start_frames[bundle.styles[0]][:1])

    def run() -> np.ndarray:
        return CachedSampler(wild).run(first, cond, Sampling(1.0, np.random.default_rng(5)))[0]

    frames = run()
    drawn = frames[:, 1:, :cont]
    assert np.isfinite(frames).all() and np.abs(drawn).max() == sampler.DRAW_LIMIT
    monkeypatch.setattr(jit, "pick", lambda kernel, twin: twin)
    np.testing.assert_array_equal(run(), frames)


def test_a_dance_from_twins_is_the_compiled_dance(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The example song's first 12 s, analysed and danced with the kernels, then with the twins (a cache of
    its own each, so both analyse): the same beats, style and frames."""
    import soundfile as sf

    from dancenet_core.generate import generate_dance
    from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, load_audio
    from dancenet_core.request import DanceRequest

    audio = load_audio(REPO / "examples" / "example_song.ogg")
    song = tmp_path / "part.wav"
    sf.write(song, audio.samples[: 12 * MADMOM_SAMPLE_RATE], MADMOM_SAMPLE_RATE)
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "compiled"))
    compiled = generate_dance(DanceRequest(song, seed=3))
    monkeypatch.setenv("DANCENET_CACHE", str(tmp_path / "twins"))
    monkeypatch.setattr(jit, "pick", lambda kernel, twin: twin)
    monkeypatch.setattr(jit, "_deferred", True)  # nor does the analysis compile them first
    twins = generate_dance(DanceRequest(song, seed=3))
    assert len(compiled.beat_times) > 10
    for name in ("beat_times", "downbeat_times", "tempo_bpm", "style", "style_probabilities", "contacts"):
        np.testing.assert_equal(getattr(twins, name), getattr(compiled, name))
    assert len(twins.motions) == len(compiled.motions) == 1
    np.testing.assert_equal(vars(twins.motions[0]), vars(compiled.motions[0]))
