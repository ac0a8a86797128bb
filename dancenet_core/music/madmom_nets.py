"""madmom's own trained recurrent networks, run with a compiled time loop instead of madmom's Python one.

madmom steps its (B)LSTM and tanh-RNN layers one frame at a time in Python, a few small numpy calls per
gate and frame: that stepping was ~70 % of the music analysis. Here the networks of an ensemble (the 8
downbeat BLSTMs, the 8 onset BRNNs) run together: each layer's input projection for every network,
direction and gate is one matrix product (BLAS), and the recurrences of all networks and both directions
go through one numba loop (hand-written because no maintained library runs madmom's peephole LSTMs on
numpy arrays without a torch-sized dependency). The weights are madmom's, read from the processors madmom
loads from its own model files; its pre- and post-processing run unchanged, but for the spectrograms the
onset and downbeat processors share (BatchedSpectrogram: the same numbers, without madmom's per-frame FFT
calls). The loop's gate nonlinearities go through an exp of its own that the compiler vectorises.

The loop runs in float64. Each network gives what madmom's own layers give when run in float64 (3e-9 at
most over a whole real song, tests to 1e-9). Against madmom's float32 processors the averaged activations
stay within 1e-4, with the same DBN beats, on the example song, the first 100 s of a real song and click
tracks (tests/test_madmom_nets.py). Over longer stretches madmom's float32 stepping itself drifts: some
cells integrate without bound on steady music and amplify any rounding, so on the whole 3.6-min DANCE_W_1
one network's float32 and float64 runs in madmom differ by up to 0.38; there the activations differ from
madmom's float32 ones by up to 0.04, and in the block-wise analysis 2 of 300 beats move by one 10-ms frame.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numba import njit

_LOG2E, _LN2_HI, _LN2_LO = 1.44269504088896338700e00, 6.93147180369123816490e-01, 1.90821492927058770002e-10
_POW2_FROM = -1081  # _POW2[n - _POW2_FROM] = 2**(n - 1) for every n that _exp can reach, subnormals and 0 included
_POW2 = np.ldexp(1.0, np.arange(_POW2_FROM - 1, 1024))


@njit(cache=True, inline="always", error_model="numpy")
def _exp(x: float) -> float:  # pragma: no cover - compiled
    """exp within 2 ulp of libm's (0 ulp for 3 in 4 inputs), in plain arithmetic and a table look-up so that
    the gate loops vectorise (numba has no vector exp without Intel's SVML): the networks' exps were ~60 %
    of the loop. Range reduction x = n ln2 + r (ln2 in two parts, Cody-Waite), Taylor series of degree 13
    for |r| <= ln2 / 2, times 2**n from the table (as 2**(n-1) * 2, so that n = 1024 is not infinite)."""
    x = min(max(x, -746.0), 710.0)
    n = np.floor(x * _LOG2E + 0.5)
    r = (x - n * _LN2_HI) - n * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    p = p * r + 1.0
    return p * _POW2[int(n) - _POW2_FROM] * 2.0


@njit(cache=True, inline="always", error_model="numpy")
def _tanh(x: float) -> float:  # pragma: no cover - compiled
    """tanh through exp, which vectorises (libm's tanh does not), within 4e-16 of it."""
    return 1.0 - 2.0 / (_exp(2.0 * x) + 1.0)


@njit(cache=True, inline="always", error_model="numpy")
def _sigmoid(x: float) -> float:  # pragma: no cover - compiled
    return 1.0 / (1.0 + _exp(-x))


@njit(cache=True, error_model="numpy")  # numpy's model: no zero-division checks, which stop vectorising
def _scan(pre: np.ndarray, bias: np.ndarray, rec: np.ndarray, peep: np.ndarray, h0: np.ndarray,
          c0: np.ndarray, backward: np.ndarray, lstm: bool) -> np.ndarray:  # pragma: no cover - compiled
    """Recurrences of C independent chains over T frames. pre [A, T, B, G*H] holds x @ W for chain
    c = a * B + b (A * B = C), bias [C, G*H] b; rec [C, H, G*H]; peep [C, 3, H] (LSTM: input, forget,
    output gate); h0, c0 [C, H]; chains with backward[c] run from the last frame, and their output is stored
    at the frame it belongs to (as madmom's BidirectionalLayer returns it): out [C / 2, T, 2, H], each
    network's forward then backward chain. G = 4 (madmom's LSTMLayer with peepholes) or 1 (its tanh
    RecurrentLayer)."""
    _, n_t, n_b, width = pre.shape
    n_c, n_h = h0.shape
    out = np.empty((n_c // 2, n_t, 2, n_h), np.float64)
    g = np.empty(width, np.float64)
    h = np.empty(n_h, np.float64)
    s = np.empty(n_h, np.float64)
    e1, e2, e3 = np.empty(n_h, np.float64), np.empty(n_h, np.float64), np.empty(n_h, np.float64)
    g_in, g_forget, g_cell, g_out = g[:n_h], g[n_h : 2 * n_h], g[2 * n_h : 3 * n_h], g[3 * n_h :]
    for c in range(n_c):
        p_in, p_forget, p_out = peep[c, 0], peep[c, 1], peep[c, 2]
        a, b = c // n_b, c % n_b
        for j in range(n_h):
            h[j] = h0[c, j]
            s[j] = c0[c, j]
        for step in range(n_t):
            t = n_t - 1 - step if backward[c] else step
            for k in range(width):
                g[k] = pre[a, t, b, k] + bias[c, k]
            for i in range(n_h):
                hi = h[i]
                for k in range(width):
                    g[k] += hi * rec[c, i, k]
            if lstm:  # one simple loop per step of the cell (as one loop it does not vectorise)
                for j in range(n_h):
                    e1[j] = _sigmoid(g_in[j] + s[j] * p_in[j])
                for j in range(n_h):
                    e2[j] = _sigmoid(g_forget[j] + s[j] * p_forget[j])
                for j in range(n_h):
                    e3[j] = _tanh(g_cell[j])
                for j in range(n_h):
                    s[j] = e3[j] * e1[j] + s[j] * e2[j]
                for j in range(n_h):
                    e1[j] = _sigmoid(g_out[j] + s[j] * p_out[j])
                for j in range(n_h):
                    h[j] = _tanh(s[j]) * e1[j]
            else:
                for j in range(n_h):
                    h[j] = _tanh(g[j])
            for j in range(n_h):
                out[c // 2, t, c % 2, j] = h[j]
    return out


def load_compiled() -> None:
    """Load the compiled loop (numba's on-disk cache, or a compile) into this process, so that worker
    processes forked from it start with it instead of each loading it again (~0.5 s)."""
    one = np.zeros((2, 1), np.float64)
    _scan(np.zeros((1, 1, 2, 1)), one, np.zeros((2, 1, 1)), np.zeros((2, 3, 1)), one, one, np.zeros(2, np.bool_), False)


class _Recurrent:
    """One bidirectional depth of the ensemble: every network's forward and backward layer as chains."""

    def __init__(self, layers: Sequence) -> None:
        # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
        from madmom.ml.nn.activations import sigmoid, tanh
        from madmom.ml.nn.layers import BidirectionalLayer, LSTMLayer, RecurrentLayer

        weights, bias, rec, peep, h0, c0 = [], [], [], [], [], []
        kinds = set()
        for layer in layers:
            if not isinstance(layer, BidirectionalLayer):
                raise TypeError(f"unsupported madmom layer {type(layer).__name__}")
            for d in (layer.fwd_layer, layer.bwd_layer):
                if isinstance(d, LSTMLayer):
                    parts = (d.input_gate, d.forget_gate, d.cell, d.output_gate)
                    gates = (d.input_gate, d.forget_gate, d.output_gate)
                    if d.activation_fn is not tanh or d.cell.activation_fn is not tanh or any(
                        p.activation_fn is not sigmoid or p.peephole_weights is None for p in gates
                    ):
                        raise TypeError("only madmom's peephole LSTM with sigmoid gates and tanh cells")
                    peep.append(np.stack([p.peephole_weights for p in gates]))
                    c0.append(d.cell_init)
                    kinds.add("lstm")
                elif type(d) is RecurrentLayer and d.activation_fn is tanh:
                    parts = (d,)
                    peep.append(np.zeros((3, d.bias.size)))
                    c0.append(np.zeros(d.bias.size))
                    kinds.add("rnn")
                else:
                    raise TypeError(f"unsupported madmom layer {type(d).__name__}")
                weights.append(np.concatenate([p.weights for p in parts], axis=1))
                bias.append(np.concatenate([np.broadcast_to(p.bias, p.weights.shape[1]) for p in parts]))
                rec.append(np.concatenate([p.recurrent_weights for p in parts], axis=1))
                h0.append(d.init)
        if len(kinds) != 1:
            raise TypeError("an ensemble depth mixes LSTM and plain recurrent layers")
        self.lstm = kinds == {"lstm"}
        self.weights = np.stack(weights).astype(np.float64)  # [C, in, G*H]
        self.bias = np.stack(bias).astype(np.float64)  # [C, G*H]
        self.rec = np.ascontiguousarray(np.stack(rec), np.float64)
        self.peep = np.ascontiguousarray(np.stack(peep), np.float64)
        self.h0 = np.ascontiguousarray(np.stack(h0), np.float64)
        self.c0 = np.ascontiguousarray(np.stack(c0), np.float64)
        self.backward = np.array([c % 2 == 1 for c in range(len(weights))])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """x [T, in] shared by all networks, or [N, T, in] one per network; returns [N, T, 2H]. The
        products come out in the layout the loop reads (no copies of the [T, C, G*H] inputs)."""
        n_c, n_in, width = self.weights.shape
        if x.ndim == 2:  # first depth: one product for every network, direction and gate
            w = self.weights.transpose(1, 0, 2).reshape(n_in, n_c * width)
            pre = (x @ w).reshape(1, len(x), n_c, width)
        else:  # later depths: each network reads its own previous depth, both directions from it
            w = self.weights.reshape(n_c // 2, 2, n_in, width).transpose(0, 2, 1, 3).reshape(n_c // 2, n_in, -1)
            pre = (x @ w).reshape(n_c // 2, x.shape[1], 2, width)  # [N, T, direction, G*H]
        out = _scan(pre, self.bias, self.rec, self.peep, self.h0, self.c0, self.backward, self.lstm)
        n_n, n_t, _, n_h = out.shape
        return out.reshape(n_n, n_t, 2 * n_h)  # [N, T, fwd H | bwd H]


class CompiledEnsemble:
    """Drop-in for a madmom NeuralNetworkEnsemble of same-shaped bidirectional networks: same inputs,
    same averaged output, computed with `_scan`."""

    def __init__(self, ensemble) -> None:
        # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
        from madmom.ml.nn.layers import FeedForwardLayer

        parallel, self.average = ensemble.processors
        nets = list(parallel.processors)
        depths = list(zip(*(net.layers for net in nets), strict=True))
        *recurrent, last = depths
        if not all(isinstance(layer, FeedForwardLayer) for layer in last):
            raise TypeError("the networks must end in a feed-forward layer")
        if len({layer.activation_fn for layer in last}) != 1:
            raise TypeError("the networks' output layers differ")
        self.depths = [_Recurrent(d) for d in recurrent]
        self.out_weights = np.stack([layer.weights.reshape(layer.weights.shape[0], -1) for layer in last])
        self.out_bias = np.stack([np.broadcast_to(layer.bias, self.out_weights.shape[2]) for layer in last])
        self.out_fn: Callable[[np.ndarray], np.ndarray] = last[0].activation_fn

    def __call__(self, data: np.ndarray) -> np.ndarray:
        x = np.asarray(data, np.float64)
        for depth in self.depths:
            x = depth(x)
        y = x @ self.out_weights + self.out_bias[:, None, :]
        return self.average([self.out_fn(net).squeeze() for net in y]).astype(np.float32)


def compiled(processor):
    """A copy of a madmom SequentialProcessor (e.g. RNNDownBeatProcessor()) whose network ensemble runs
    compiled; its other steps are madmom's own objects."""
    # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
    from madmom.ml.nn import NeuralNetworkEnsemble
    from madmom.processors import SequentialProcessor

    steps = [CompiledEnsemble(p) if isinstance(p, NeuralNetworkEnsemble) else p for p in processor.processors]
    if sum(isinstance(p, CompiledEnsemble) for p in steps) != 1:
        raise TypeError(f"{type(processor).__name__} holds no single network ensemble")
    return SequentialProcessor(steps)


class BatchedSpectrogram:
    """madmom's FramedSignalProcessor, ShortTimeFourierTransformProcessor and magnitude Spectrogram, with
    the FFTs of a block of frames in one call instead of one scipy call per frame, and the complex STFT
    kept one block at a time instead of whole (madmom's per-frame loop and its [frames, bins] complex array
    were a third of the analysis once the networks were compiled). Same frames, the same float64 window
    product and transform rounded to complex64, the same magnitudes (equal to madmom's in the tests). The
    result is madmom's Spectrogram; its `stft` is madmom's ShortTimeFourierTransform with no frames but
    every attribute the filterbank and difference steps read (frames, window, bin frequencies): only for
    steps that need no STFT values, such as the onset and downbeat processors' (no phase)."""

    CHUNK = 512  # frames per FFT call: 16 MB of float64 at 4096 samples

    def __init__(self, frames, stft) -> None:
        if stft.fft_size is not None or stft.circular_shift or frames.end != "normal" or frames.num_frames:
            raise TypeError("only madmom's default STFT of centred frames up to the end of the signal")
        self.frames, self.stft = frames, stft

    def __call__(self, sig: np.ndarray):
        # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
        import scipy.fft
        from madmom.audio.spectrogram import Spectrogram
        from madmom.audio.stft import ShortTimeFourierTransform

        framed = self.frames(sig)
        size, signal = framed.frame_size, np.asarray(framed.signal)
        if signal.ndim != 1 or not np.issubdtype(signal.dtype, np.floating):
            raise TypeError("only a mono float signal (madmom scales integer ones)")
        window = self.stft.window(size) if callable(self.stft.window) else self.stft.window
        bins = size // 2 + (1 if self.stft.include_nyquist else 0)
        # madmom's signal_frame: frame i starts at int(i * hop) - size // 2 - origin, zeros outside the signal
        starts = (np.arange(framed.num_frames) * framed.hop_size).astype(np.int64) - size // 2 - framed.origin
        padded = np.concatenate([np.zeros(size, signal.dtype), signal, np.zeros(size, signal.dtype)])
        views = np.lib.stride_tricks.sliding_window_view(padded, size)
        magnitude = np.empty((framed.num_frames, bins), np.float32)
        for i in range(0, framed.num_frames, self.CHUNK):
            chunk = views[starts[i : i + self.CHUNK] + size]
            spectrum = scipy.fft.rfft(chunk * window if window is not None else chunk, axis=1)[:, :bins]
            np.abs(spectrum.astype(np.complex64), out=magnitude[i : i + self.CHUNK])
        stft = np.zeros((0, bins), np.complex64).view(ShortTimeFourierTransform)
        stft.frames, stft.window, stft.fft_window, stft.fft_size = framed, self.stft.window, window, size
        stft.circular_shift, stft.include_nyquist = False, self.stft.include_nyquist
        spectrogram = magnitude.view(Spectrogram)
        spectrogram.stft = stft
        return spectrogram


class OnsetAndBeat:
    """madmom's RNNOnsetProcessor and RNNDownBeatProcessor (networks compiled) on one signal, sharing the
    magnitude spectrograms (BatchedSpectrogram): both frame the signal at 1024, 2048 and 4096 samples and
    100 fps with the same window; each then runs its own filterbank, log and difference steps. Returns
    (onset [T], beat and downbeat [T, 2]), what the two processors return."""

    def __init__(self) -> None:
        # madmom takes ~0.9 s to load: only an analysis that misses the cache loads it
        from madmom.audio.spectrogram import FilteredSpectrogramProcessor
        from madmom.features.downbeats import RNNDownBeatProcessor
        from madmom.features.onsets import RNNOnsetProcessor
        from madmom.processors import SequentialProcessor

        onset, beat = compiled(RNNOnsetProcessor()), compiled(RNNDownBeatProcessor())
        (on_signal, on_multi, self.on_stack), *self.on_tail = onset.processors[0].processors, *onset.processors[1:]
        (db_signal, db_multi, self.db_stack), *self.db_tail = beat.processors[0].processors, *beat.processors[1:]
        if vars(on_signal) != vars(db_signal):
            raise TypeError("the onset and beat processors read the signal differently")
        self.signal = on_signal
        self.branches = []
        for on_branch, db_branch in zip(on_multi.processors, db_multi.processors, strict=True):
            (frames, stft, *on_rest), (db_frames, db_stft, *db_rest) = on_branch.processors, db_branch.processors
            if _framing(frames, self.signal) != _framing(db_frames, self.signal) or not _same_stft(stft, db_stft):
                raise TypeError("the onset and beat processors frame the signal differently")
            if not all(isinstance(rest[0], FilteredSpectrogramProcessor) for rest in (on_rest, db_rest)):
                raise TypeError("a step after the STFT that may need more than its magnitudes")
            self.branches.append((BatchedSpectrogram(frames, stft), SequentialProcessor(on_rest),
                                  SequentialProcessor(db_rest)))

    def __call__(self, sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sig = self.signal(sig)
        on_parts, db_parts = [], []
        for spectrogram, on_rest, db_rest in self.branches:
            spec = spectrogram(sig)
            on_parts.append(on_rest(spec))
            db_parts.append(db_rest(spec))
        onset, beat = self.on_stack(on_parts), self.db_stack(db_parts)
        for step in self.on_tail:
            onset = step(onset)
        for step in self.db_tail:
            beat = step(beat)
        return onset, beat


def _framing(frames, signal) -> dict:
    """A FramedSignalProcessor's settings, with a frame rate turned into the hop it gives at the signal's rate."""
    settings = dict(vars(frames))
    fps = settings.pop("fps")
    if fps:
        settings["hop_size"] = signal.sample_rate / float(fps)
    return settings


def _same_stft(a, b) -> bool:
    """Two ShortTimeFourierTransformProcessors give the same transform (their cached windows aside)."""
    keys = set(vars(a)) | set(vars(b))
    return all(np.array_equal(getattr(a, k, None), getattr(b, k, None)) for k in keys)
