"""The compiled networks against madmom's own processors: activations to 1e-4, and the beats and downbeats
madmom's DBN tracks from them, on synthetic music, click tracks and real songs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from made_up import click_track, music

from dancenet_core.music.audio import MADMOM_SAMPLE_RATE, load_audio
from dancenet_core.music.madmom_nets import BatchedSpectrogram, CompiledEnsemble, OnsetAndBeat, compiled

REPO = Path(__file__).resolve().parents[2]
ATOL = 1e-4


def madmom_and_ours(x: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """(onset, beat/downbeat) activations from madmom's processors and from OnsetAndBeat."""
    from madmom.audio.signal import Signal
    from madmom.features.downbeats import RNNDownBeatProcessor
    from madmom.features.onsets import RNNOnsetProcessor

    sig = Signal(x, sample_rate=MADMOM_SAMPLE_RATE, num_channels=1)
    return (RNNOnsetProcessor()(sig), RNNDownBeatProcessor()(sig)), OnsetAndBeat()(sig)


def tracked(act: np.ndarray) -> np.ndarray:
    """madmom's downbeat DBN as the analysis runs it: [beat time, position in bar]."""
    from madmom.features.downbeats import DBNDownBeatTrackingProcessor

    return DBNDownBeatTrackingProcessor(beats_per_bar=[3, 4], fps=100)(act)


def assert_same(x: np.ndarray) -> None:
    (onset, beat), (our_onset, our_beat) = madmom_and_ours(x)
    assert our_onset.shape == onset.shape
    assert our_beat.shape == beat.shape
    assert our_onset.dtype == onset.dtype == np.float32
    assert our_beat.dtype == beat.dtype
    np.testing.assert_allclose(our_onset, onset, rtol=0, atol=ATOL)
    np.testing.assert_allclose(our_beat, beat, rtol=0, atol=ATOL)
    np.testing.assert_array_equal(tracked(our_beat), tracked(beat))


def test_synthetic_music_matches_madmom() -> None:
    """4 s only: on these steady chords one cell of a downbeat network integrates without bound (its state
    passes 400 by 4.3 s), and from there two float64 runs that merely sum in another order drift 1e-4
    apart, as do madmom's own float32 and float64 runs (see dancenet_core/madmom_nets.py)."""
    assert_same(music(4.0, seed=5))


@pytest.mark.parametrize("bpm", [60, 120, 180])
def test_click_track_beats_unchanged(bpm: int) -> None:
    x, _ = click_track(bpm)
    assert_same(x)


def test_example_song_matches_madmom() -> None:
    """The bundled 53-s waltz, whole."""
    assert_same(load_audio(REPO / "examples" / "example_song.ogg").samples)


@pytest.mark.data  # 100 s of a real song through madmom's own networks (the example song: the test above)
def test_real_song_matches_madmom(shared_data: Path) -> None:
    """The first 100 s of a real waltz recording."""
    x = load_audio(shared_data / "dance_with_melody" / "DANCE_W_1.ogg").samples
    assert_same(x[: 100 * MADMOM_SAMPLE_RATE])


def test_each_network_of_the_ensemble() -> None:
    """Every one of the 8 downbeat networks on its own, not only their average (which could hide one)."""
    from madmom.features.downbeats import RNNDownBeatProcessor

    proc = RNNDownBeatProcessor()
    pre, ensemble = proc.processors[0], proc.processors[1]
    data = pre(music(4.0, seed=2))
    for net in ensemble.processors[0].processors:
        single = CompiledEnsemble(type(ensemble)([net]))
        np.testing.assert_allclose(single(data), net(data), rtol=0, atol=ATOL)


def test_refuses_what_it_cannot_run() -> None:
    """A processor without a network ensemble, or a layer type the loop does not know, is an error."""
    from madmom.audio.chroma import DeepChromaProcessor
    from madmom.ml.nn import NeuralNetwork, NeuralNetworkEnsemble
    from madmom.ml.nn.layers import FeedForwardLayer

    with pytest.raises(TypeError):
        compiled(DeepChromaProcessor())  # its ensemble is feed-forward only
    dense = FeedForwardLayer(np.ones((2, 2), np.float32), np.zeros(2, np.float32))
    with pytest.raises(TypeError):
        CompiledEnsemble(NeuralNetworkEnsemble([NeuralNetwork([dense, dense])]))


def _in_float64(layer) -> None:
    """Cast a madmom layer's weights (and its gates', directions') to float64, in place."""
    for key, value in list(vars(layer).items()):
        if isinstance(value, np.ndarray) and value.dtype == np.float32:
            setattr(layer, key, value.astype(np.float64))
        elif hasattr(value, "activate"):
            _in_float64(value)


def test_networks_equal_madmoms_own_layers_in_float64(shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On 30 s of a real song, each of the 8 downbeat networks equals madmom's own layers run in float64
    (its code, its weights cast) to rounding: the 1e-4 left against madmom's float32 processors is the
    float32 rounding of madmom's own stepping."""
    import madmom.ml.nn.layers as layers
    from madmom.features.downbeats import RNNDownBeatProcessor

    x = load_audio(shared_data / "dance_with_melody" / "DANCE_W_1.ogg").samples[: 30 * MADMOM_SAMPLE_RATE]
    proc = RNNDownBeatProcessor()
    data = proc.processors[0](x)
    nets = proc.processors[1].processors[0].processors
    ours = CompiledEnsemble(proc.processors[1])
    hidden = data.astype(np.float64)
    for depth in ours.depths:
        hidden = depth(hidden)
    logits = hidden @ ours.out_weights + ours.out_bias[:, None, :]
    monkeypatch.setattr(layers, "NN_DTYPE", np.float64)
    for net, net_logits in zip(nets, logits, strict=True):
        for layer in net.layers:
            _in_float64(layer)
        np.testing.assert_allclose(ours.out_fn(net_logits), net(data.astype(np.float64)), rtol=0, atol=1e-9)


@pytest.mark.parametrize("frame_size", [1024, 2048, 4096])
@pytest.mark.parametrize("n", [500, 44101, 3 * MADMOM_SAMPLE_RATE + 7])
def test_batched_spectrogram_matches_madmom(frame_size: int, n: int) -> None:
    """Every frame, padded edges and signals shorter than a frame included, bit for bit as madmom's
    spectrogram of its STFT, with what madmom's filterbank and difference steps read from the STFT."""
    from madmom.audio.signal import FramedSignalProcessor, Signal
    from madmom.audio.spectrogram import Spectrogram, SpectrogramDifference
    from madmom.audio.stft import ShortTimeFourierTransformProcessor
    from madmom.processors import SequentialProcessor

    sig = Signal(music(n / MADMOM_SAMPLE_RATE + 0.1, seed=3)[:n], sample_rate=MADMOM_SAMPLE_RATE, num_channels=1)
    frames, stft = FramedSignalProcessor(frame_size=frame_size, fps=100), ShortTimeFourierTransformProcessor()
    theirs, ours = Spectrogram(SequentialProcessor((frames, stft))(sig)), BatchedSpectrogram(frames, stft)(sig)
    assert type(ours) is type(theirs) and type(ours.stft) is type(theirs.stft)
    assert ours.shape == theirs.shape and ours.dtype == theirs.dtype
    np.testing.assert_array_equal(ours, theirs)
    np.testing.assert_array_equal(ours.bin_frequencies, theirs.bin_frequencies)
    diff = {k: SpectrogramDifference(s, diff_ratio=0.5) for k, s in (('ours', ours), ('theirs', theirs))}
    np.testing.assert_array_equal(diff['ours'], diff['theirs'])
