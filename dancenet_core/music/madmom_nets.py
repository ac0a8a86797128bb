"""madmom's own trained recurrent networks, run with a compiled time loop instead of madmom's Python one.

madmom steps its (B)LSTM and tanh-RNN layers one frame at a time in Python, a few small numpy calls per
gate and frame: that stepping was ~70 % of the music analysis. Here the networks of an ensemble (the 8
downbeat BLSTMs, the 8 onset BRNNs) run together: each layer's input projection for a network's
directions and gates is one matrix product (BLAS), and the recurrences of both directions go through one
numba loop (hand-written because no maintained library runs madmom's peephole LSTMs on numpy arrays
without a torch-sized dependency). The weights are madmom's, read from the processors madmom
loads from its own model files; its pre- and post-processing run unchanged, but for the spectrograms the
onset and downbeat processors share (BatchedSpectrogram: the same numbers, without madmom's per-frame FFT
calls). The loop's gate nonlinearities go through an exp of its own that the compiler vectorises; each
gate's units are padded to a whole number of vectors, and the recurrent product adds four rows per pass.

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

from .. import jit

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


LANES = 8  # float64 in a 512-bit vector: each gate's units padded to a multiple, so no loop has a remainder


@njit(cache=True, error_model="numpy")  # numpy's model: no zero-division checks, which stop vectorising
def _scan(pre: np.ndarray, bias: np.ndarray, rec: np.ndarray, peep: np.ndarray, h0: np.ndarray,
          c0: np.ndarray, backward: np.ndarray, lstm: bool, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """Recurrences of C independent chains over T frames. pre [A, T, B, G*H] holds x @ W for chain
    c = a * B + b (A * B = C), bias [C, G*H] b; rec [C, H, G*S] with gate q of unit j in column q * S + j,
    S >= H a multiple of LANES, the padding columns zero; peep [C, 3, S] (LSTM: input, forget, output gate;
    zero past H); h0, c0 [C, H]; chains with backward[c] run from the last frame, and their output is
    stored at the frame it belongs to (as madmom's BidirectionalLayer returns it) in out [C / 2, T, 2, H],
    each network's forward then backward chain. G = 4 (madmom's LSTMLayer with peepholes) or 1 (its tanh
    RecurrentLayer). The padded units start at zero and stay zero; only the first H reach the output."""
    _, n_t, n_b, width = pre.shape
    n_c, n_h = h0.shape
    n_gates, stride = width // n_h, peep.shape[2]
    n_k = n_gates * stride
    g = np.zeros(n_k, np.float64)
    h, s = np.zeros(stride, np.float64), np.zeros(stride, np.float64)
    e1, e2, e3 = np.zeros(stride, np.float64), np.zeros(stride, np.float64), np.zeros(stride, np.float64)
    g_in, g_forget, g_cell, g_out = g[:stride], g[stride : 2 * stride], g[2 * stride : 3 * stride], g[3 * stride :]
    for c in range(n_c):
        p_in, p_forget, p_out = peep[c, 0], peep[c, 1], peep[c, 2]
        a, b = c // n_b, c % n_b
        for j in range(n_h):
            h[j] = h0[c, j]
            s[j] = c0[c, j]
        for step in range(n_t):
            t = n_t - 1 - step if backward[c] else step
            for q in range(n_gates):
                for j in range(n_h):
                    g[q * stride + j] = pre[a, t, b, q * n_h + j] + bias[c, q * n_h + j]
            n_four = n_h // 4 * 4
            for i in range(0, n_four, 4):  # four rows per pass over g (a quarter of its loads and stores),
                # each product still added on its own and in row order: the sums of one row at a time, bit for bit
                h_0, h_1, h_2, h_3 = h[i], h[i + 1], h[i + 2], h[i + 3]
                r_0, r_1, r_2, r_3 = rec[c, i], rec[c, i + 1], rec[c, i + 2], rec[c, i + 3]
                for k in range(n_k):
                    g[k] = (((g[k] + h_0 * r_0[k]) + h_1 * r_1[k]) + h_2 * r_2[k]) + h_3 * r_3[k]
            for i in range(n_four, n_h):
                h_i, r_i = h[i], rec[c, i]
                for k in range(n_k):
                    g[k] += h_i * r_i[k]
            if lstm:  # one simple loop per step of the cell (as one loop it does not vectorise)
                for j in range(stride):
                    e1[j] = _sigmoid(g_in[j] + s[j] * p_in[j])
                for j in range(stride):
                    e2[j] = _sigmoid(g_forget[j] + s[j] * p_forget[j])
                for j in range(stride):
                    e3[j] = _tanh(g_cell[j])
                for j in range(stride):
                    s[j] = e3[j] * e1[j] + s[j] * e2[j]
                for j in range(stride):
                    e1[j] = _sigmoid(g_out[j] + s[j] * p_out[j])
                for j in range(stride):
                    h[j] = _tanh(s[j]) * e1[j]
            else:
                for j in range(stride):
                    h[j] = _tanh(g[j])
            for j in range(n_h):
                out[c // 2, t, c % 2, j] = h[j]


def _exp_numpy(x: np.ndarray) -> np.ndarray:
    """`_exp` on an array, the same operations in the same order (so the same bits); exp(710) is inf here
    too (the caller silences numpy's overflow warning)."""
    x = np.minimum(np.maximum(x, -746.0), 710.0)
    n = np.floor(x * _LOG2E + 0.5)
    r = (x - n * _LN2_HI) - n * _LN2_LO
    p = r * (1.0 / 6227020800.0) + 1.0 / 479001600.0
    for c in (1.0 / 39916800.0, 1.0 / 3628800.0, 1.0 / 362880.0, 1.0 / 40320.0, 1.0 / 5040.0, 1.0 / 720.0,
              1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0):  # fmt: skip
        p *= r
        p += c
    p *= _POW2[n.astype(np.int64) - _POW2_FROM]
    p *= 2.0
    return p


def _scan_numpy(pre: np.ndarray, bias: np.ndarray, rec: np.ndarray, peep: np.ndarray, h0: np.ndarray,
                c0: np.ndarray, backward: np.ndarray, lstm: bool, out: np.ndarray) -> None:
    """`_scan` in numpy, every chain a step at a time together: the same sums in the same order (the
    recurrent product added row by row), the same exp, so the same output bit for bit (dancenet_core/jit.py:
    what runs before the loop is compiled). The padding units are left out: they stay zero and reach nothing."""
    _, n_t, n_b, width = pre.shape
    n_c, n_h = h0.shape
    n_gates, stride = width // n_h, peep.shape[2]
    chains = np.arange(n_c)
    steps = np.arange(n_t)[:, None]
    # [T, C, G*H]: each chain's input at each of its steps (backward chains from the last frame), plus bias
    inputs = pre[chains // n_b, np.where(backward, n_t - 1 - steps, steps), chains % n_b] + bias
    # [H, C, G*H]: rows outermost, each row's products of all chains one contiguous array
    rec = rec.reshape(n_c, n_h, n_gates, stride)[..., :n_h].reshape(n_c, n_h, width).transpose(1, 0, 2).copy()
    p_in, p_forget, p_out = (np.ascontiguousarray(peep[:, i, :n_h]) for i in range(3))
    h, s = h0.astype(np.float64), c0.astype(np.float64)
    # Row 0 the step's input, rows 1..H the recurrent products: numpy reduces a non-innermost axis one row after
    # another, so one call gives the loop's sums in its order (((x + p_0) + p_1) + ...) without H calls a step
    terms = np.empty((n_h + 1, n_c, width))
    for step in range(n_t):  # under np.errstate(over="ignore"): see __call__
        terms[0] = inputs[step]
        np.multiply(h.T[:, :, None], rec, out=terms[1:])
        g = np.add.reduce(terms, axis=0)
        if lstm:
            g_in, g_forget, g_cell, g_out = (g[:, q * n_h : (q + 1) * n_h] for q in range(4))
            e = _exp_numpy(np.stack([-(g_in + s * p_in), -(g_forget + s * p_forget), 2.0 * g_cell]))
            e1, e2, e3 = 1.0 / (1.0 + e[0]), 1.0 / (1.0 + e[1]), 1.0 - 2.0 / (e[2] + 1.0)
            s = e3 * e1 + s * e2
            e = _exp_numpy(np.stack([-(g_out + s * p_out), 2.0 * s]))
            h = (1.0 - 2.0 / (e[1] + 1.0)) * (1.0 / (1.0 + e[0]))
        else:
            h = 1.0 - 2.0 / (_exp_numpy(2.0 * g) + 1.0)
        t = np.where(backward, n_t - 1 - step, step)
        out[chains // 2, t, chains % 2] = h


KERNELS = (_scan,)  # what jit.pick chooses between, for the warm-up


def load_compiled() -> None:
    """Load the compiled loop (numba's on-disk cache, or a compile) into this process, so that worker
    processes forked from it start with it instead of each loading it again (~0.5 s)."""
    one = np.zeros((2, 1), np.float64)
    _scan(np.zeros((1, 1, 2, 1)), one, np.zeros((2, 1, LANES)), np.zeros((2, 3, LANES)), one, one,
          np.zeros(2, np.bool_), False, np.zeros((1, 1, 2, 1)))


class _Recurrent:
    """One bidirectional depth of the ensemble: every network's forward and backward layer as chains."""

    GROUP = 1  # networks whose input products are computed, then scanned, together

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
        rec, peep = np.stack(rec), np.stack(peep)  # [C, H, G*H], [C, 3, H]: padded to S units a gate
        n_c, n_h, width = rec.shape
        stride = -(-n_h // LANES) * LANES
        self.rec = np.zeros((n_c, n_h, width // n_h, stride), np.float64)
        self.rec[..., :n_h] = rec.reshape(n_c, n_h, width // n_h, n_h)
        self.rec = self.rec.reshape(n_c, n_h, -1)
        self.peep = np.zeros((n_c, 3, stride), np.float64)
        self.peep[..., :n_h] = peep
        self.h0 = np.ascontiguousarray(np.stack(h0), np.float64)
        self.c0 = np.ascontiguousarray(np.stack(c0), np.float64)
        self.backward = np.array([c % 2 == 1 for c in range(len(weights))])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """x [T, in] shared by all networks, or [N, T, in] one per network; returns [N, T, 2H]. The
        products come out in the layout the loop reads (no copies of the [T, C, G*H] inputs), a group of
        networks at a time: all 8 networks' products are ~90 MB for a 70-s block, which a fresh worker
        process faults in page by page (slowly in a virtual machine); a group's fit in a few MB."""
        n_c, n_in, width = self.weights.shape
        n_n, n_t, n_h = n_c // 2, x.shape[-2], self.h0.shape[1]
        out = np.empty((n_n, n_t, 2, n_h), np.float64)
        scan = jit.pick(_scan, _scan_numpy)
        group = self.GROUP if scan is _scan else n_n  # the twin's time goes into numpy's calls per frame: all at once
        for n0 in range(0, n_n, group):
            nets, chains = slice(n0, n0 + group), slice(2 * n0, 2 * (n0 + group))
            if x.ndim == 2:  # first depth: one product for every network, direction and gate of the group
                w = self.weights[chains].transpose(1, 0, 2).reshape(n_in, -1)
                pre = (x @ w).reshape(1, n_t, -1, width)
            else:  # later depths: each network reads its own previous depth, both directions from it
                w = self.weights[chains].reshape(-1, 2, n_in, width).transpose(0, 2, 1, 3).reshape(-1, n_in, 2 * width)
                pre = (x[nets] @ w).reshape(-1, n_t, 2, width)  # [N, T, direction, G*H]
            with np.errstate(over="ignore"):  # the twin's exp(710) = inf, as the loop's
                scan(pre, self.bias[chains], self.rec[chains], self.peep[chains], self.h0[chains],
                     self.c0[chains], self.backward[chains], self.lstm, out[nets])
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

    CHUNK = 128  # frames per FFT call: ~12 MB of temporaries at 4096 samples

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
            del spec  # before the next frame size's (57 MB at 4096 samples for 70 s): a smaller peak to fault in
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
