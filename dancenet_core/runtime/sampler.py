"""Autoregressive generation: cached incremental inference (WaveNet-style per-layer queues). The naive way
it is compared with (recompute the whole receptive field every frame, as the authors' release does) runs the
torch network: `nets/dancenet.py`'s `naive_run`.

The cached loop is compiled with numba: per frame it is a handful of small matrix-vector products, where
torch's or numpy's per-call overhead (microseconds each, hundreds of calls per frame) would cost more
than the arithmetic. Weights are re-laid out once: each layer's filter and gate convs fused into one
matrix, the conditioning (music code + style) precomputed for the whole song, and all layers' skip convs
applied as one matrix. Randomness comes in as arrays drawn by the caller's seeded generator, so a seed
gives the same dance on any machine.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numba
import numpy as np

from .. import jit
from ..progress import Progress
from .config import DanceNetConfig
from .numpy_nets import NumpyDanceNet

CHUNK = 250  # frames per compiled call, between which progress is reported and cancellation checked
# Each drawn value is held within this many standard deviations (normalised units): the capture reaches 15 and
# the shipped weights' dances 10.7, so they never meet it; a model whose sigma head runs away once (a run trained
# from scratch did so in 5 of 90 dances, 2.5 -> 2.5e7 -> NaN within a frame) keeps dancing instead of decoding
# to zero-norm rotations. Training clips its own draws to the same limit.
DRAW_LIMIT = 16.0
WindowConditioning = Callable[[np.ndarray, np.ndarray], np.ndarray]


class TorchDanceNet(Protocol):
    """DanceNet's torch network (`nets/dancenet.py`), which training and evaluation pass, as the sampler uses
    it: described here rather than imported, so that the runtime never imports torch."""

    cfg: DanceNetConfig

    def to_numpy(self) -> NumpyDanceNet: ...

    def exact_conditioner(self) -> WindowConditioning: ...


def as_numpy(model: TorchDanceNet | NumpyDanceNet) -> NumpyDanceNet:
    """The network as arrays: a runtime one as it is, a torch one (training, evaluation) converted."""
    return model if isinstance(model, NumpyDanceNet) else model.to_numpy()


def _window_conditioner(model: TorchDanceNet | NumpyDanceNet) -> WindowConditioning:
    """Conditioning [B, T, C] of windows of music [B, T, F] and styles [B] in float64 (why: see
    `NumpyDanceNet.conditioning`), by the numpy runtime or by a float64 copy of the torch model."""
    return model.conditioning if isinstance(model, NumpyDanceNet) else model.exact_conditioner()


def music_conditioning(model: TorchDanceNet | NumpyDanceNet, music: np.ndarray, style: int) -> np.ndarray:
    """Conditioning [T, C] for a whole song: 8-s windows overlapping by 2 s, cross-faded into one code.

    Windows keep the encoder on the length it was trained on, so any song length works. The code is computed
    in float64 and rounded to float32 once, at the end: the numpy runtime and torch then give the same code.
    """
    cfg = model.cfg
    t = len(music)
    win, ov = cfg.music_window, cfg.music_overlap
    hop = win - ov
    starts = [0] if t <= win else list(range(0, t - win, hop)) + [t - win]
    total = np.zeros((t, cfg.music_code + cfg.style_dim))
    weight = np.zeros((t, 1))
    ramp = np.ones(min(win, t))
    if len(starts) > 1:
        ramp[:ov] = np.linspace(0.0, 1.0, ov + 2)[1:-1]
        ramp[-ov:] = ramp[:ov][::-1].copy()
    window_conditioning = _window_conditioner(model)
    for i in range(0, len(starts), 32):  # bounded memory for long songs
        chunk = starts[i : i + 32]
        batch = np.stack([music[s : s + win] for s in chunk]).astype(np.float32)
        cond = window_conditioning(batch, np.full(len(chunk), style, dtype=np.int64))
        for s, c in zip(chunk, cond, strict=True):
            total[s : s + len(c)] += c * ramp[:, None]
            weight[s : s + len(c)] += ramp[:, None]
    return (total / weight).astype(np.float32)


@dataclass
class Sampling:
    """How a frame is drawn from the mixture: temperature scales sigma; the draws come from `rng`."""

    temperature: float
    rng: np.random.Generator


@numba.njit  # compiled into `_generate` and cached with it, not a kernel of its own
def _component(out: np.ndarray, mixtures: int, draw: float, temperature: float) -> int:
    """The mixture component: softmax over the logits `out[:mixtures]`, chosen by a uniform `draw` (at
    temperature 0 the most likely one). One body for the kernel and, as `py_func`, its numpy twin: math.exp is
    the C library's exp in both."""
    m = out[0]
    for i in range(1, mixtures):
        m = max(m, out[i])
    total = 0.0
    for i in range(mixtures):
        total += math.exp(out[i] - m)
    u = draw * total
    acc = 0.0
    for i in range(mixtures):
        acc += math.exp(out[i] - m)
        if temperature <= 0.0:  # deterministic: the most likely component's mean
            if out[i] == m:
                return i
        elif u < acc:
            return i
    return mixtures - 1


class Net(NamedTuple):
    """The network as the kernel reads it, re-laid out by `CachedSampler` (a named tuple of arrays is one typed
    argument to a numba kernel): the motion encoder, each layer's fused filter|gate|next-tap matrix, residual
    and skip convs, the decoder, the input skip ([0, O] when the model has none) and the modelled channels."""

    dilations: np.ndarray
    enc_w0: np.ndarray
    enc_b0: np.ndarray
    enc_w1: np.ndarray
    enc_b1: np.ndarray
    enc_w2: np.ndarray
    enc_b2: np.ndarray
    w_np: np.ndarray
    w_res: np.ndarray
    b_res: np.ndarray
    skip_w: np.ndarray
    skip_b: np.ndarray
    dec_w0: np.ndarray
    dec_b0: np.ndarray
    dec_w1: np.ndarray
    dec_b1: np.ndarray
    in_w: np.ndarray
    in_b: np.ndarray
    modelled: np.ndarray


class Head(NamedTuple):
    """How the outputs are read and drawn from: components, continuous channels, the floor of log sigma, the
    temperature, and whether each component's mean is an offset from the previous frame."""

    mixtures: int
    cont: int
    min_log_sigma: np.float32
    temperature: np.float32
    residual: bool


class Run(NamedTuple):
    """One call's arrays: the frames [T, B, D] (written), the outputs [T, B, O] (recorded if sized), each layer's
    queue, the song's layer conditioning [T, L, 2R], the draws (`eps`, `unif`, by absolute frame) and the frames
    to feed instead of samples (`teacher`, [0, B, D] for none)."""

    frames: np.ndarray
    outputs: np.ndarray
    queues: np.ndarray
    layer_cond: np.ndarray
    eps: np.ndarray
    unif: np.ndarray
    teacher: np.ndarray


@numba.njit(cache=True)
def _generate(run: Run, net: Net, head: Head, t0: int, t1: int) -> None:
    """Frames t0..t1-1 (frame t from frames < t). With `teacher` non-empty, feed those frames instead of
    samples (used to check the cached pass equals the full forward). Outputs are recorded if sized."""
    frames, outputs, queues, layer_cond, eps, unif, teacher = run
    (dilations, enc_w0, enc_b0, enc_w1, enc_b1, enc_w2, enc_b2, w_np, w_res, b_res, skip_w, skip_b,
     dec_w0, dec_b0, dec_w1, dec_b1, in_w, in_b, modelled) = net
    mixtures, cont, min_log_sigma, temperature, residual = head
    bsz = frames.shape[1]
    n_layers = w_np.shape[0]
    r = w_res.shape[1]
    zero = np.float32(0.0)
    gated = np.empty((n_layers, r), np.float32)
    for t in range(t0, t1):
        slot = t - 1
        for b in range(bsz):
            h = np.maximum(frames[t - 1, b] @ enc_w0 + enc_b0, zero)
            h = np.maximum(h @ enc_w1 + enc_b1, zero)
            x = h @ enc_w2 + enc_b2
            for li in range(n_layers):
                k = slot % dilations[li]
                # a = [filter|gate input from this frame | what this frame adds d frames later]
                a = x @ w_np[li]
                for c in range(r):
                    zf = a[c] + queues[li, k, b, c] + layer_cond[t, li, c]
                    zg = a[r + c] + queues[li, k, b, r + c] + layer_cond[t, li, r + c]
                    # tanh x sigmoid, in float64 (libm's tanh, which the numpy twin calls as math.tanh)
                    gated[li, c] = np.tanh(np.float64(zf)) * (0.5 + 0.5 * np.tanh(0.5 * zg))
                queues[li, k, b] = a[2 * r :]
                x = x + gated[li] @ w_res[li] + b_res[li]
            s = np.maximum(gated.reshape(n_layers * r) @ skip_w + skip_b, zero)
            s = np.maximum(s @ dec_w0 + dec_b0, zero)
            out = s @ dec_w1 + dec_b1
            if in_w.shape[0] > 0:  # the input-skip path: the last frame straight to the outputs
                out += frames[t - 1, b] @ in_w + in_b
            if residual:  # each component's mean is an offset from the previous frame
                for i in range(mixtures):
                    for j in range(cont):
                        if modelled[j]:
                            out[mixtures + i * cont + j] += frames[t - 1, b, j]
            if outputs.shape[0] > 0:
                outputs[t, b] = out
            if teacher.shape[0] > 0:
                frames[t, b] = teacher[t, b]
                continue
            comp = _component(out, mixtures, unif[t, b], temperature)
            mu0 = mixtures + comp * cont
            ls0 = mixtures + mixtures * cont + comp * cont
            for j in range(cont):
                if modelled[j]:
                    raw = np.float64(out[ls0 + j] - min_log_sigma)
                    soft = raw if raw > 20.0 else np.log1p(np.exp(raw))
                    sigma = np.float32(np.exp(np.float64(min_log_sigma) + soft))
                    frames[t, b, j] = min(max(out[mu0 + j] + sigma * temperature * eps[t, b, j], -DRAW_LIMIT),
                                          DRAW_LIMIT)
                else:
                    frames[t, b, j] = 0.0
            c0 = mixtures + 2 * mixtures * cont
            for j in range(frames.shape[2] - cont):
                frames[t, b, cont + j] = 1.0 if out[c0 + j] > 0.0 else 0.0


def _generate_numpy(run: Run, net: Net, head: Head, t0: int, t1: int) -> None:
    """`_generate` in numpy and Python (dancenet_core.jit: what runs before it is compiled), the same numbers
    bit for bit: each product through the BLAS call numba makes for `vector @ matrix` (scipy's sgemv, no
    transpose, on the matrix's transpose), the float32 and float64 steps as the kernel does them, and its
    exp, log1p and tanh through Python's math module, which calls the C library the kernel calls."""
    from scipy.linalg.blas import sgemv  # the library numba's BLAS calls go to

    frames, outputs, queues, layer_cond, eps, unif, teacher = run
    (dilations, enc_w0, enc_b0, enc_w1, enc_b1, enc_w2, enc_b2, w_np, w_res, b_res, skip_w, skip_b,
     dec_w0, dec_b0, dec_w1, dec_b1, in_w, in_b, modelled) = net
    mixtures, cont, min_log_sigma, temperature, residual = head

    def dot(v: np.ndarray, m: np.ndarray) -> np.ndarray:
        return sgemv(1.0, m.T, v)

    def tanh(v: np.ndarray) -> np.ndarray:
        return np.fromiter(map(math.tanh, v.tolist()), np.float64, len(v))

    n_layers, r = w_np.shape[0], w_res.shape[1]
    zero = np.float32(0.0)
    gated = np.empty((n_layers, r), np.float32)
    kept = np.flatnonzero(modelled)
    c0 = mixtures + 2 * mixtures * cont
    for t in range(t0, t1):
        slot = t - 1
        for b in range(frames.shape[1]):
            h = np.maximum(dot(frames[t - 1, b], enc_w0) + enc_b0, zero)
            h = np.maximum(dot(h, enc_w1) + enc_b1, zero)
            x = dot(h, enc_w2) + enc_b2
            for li in range(n_layers):
                k = slot % dilations[li]
                a = dot(x, w_np[li])
                z = a[: 2 * r] + queues[li, k, b, : 2 * r] + layer_cond[t, li]
                gated[li] = tanh(z[:r]) * (0.5 + 0.5 * tanh(0.5 * z[r:].astype(np.float64)))
                queues[li, k, b] = a[2 * r :]
                x = x + dot(gated[li], w_res[li]) + b_res[li]
            s = np.maximum(dot(gated.reshape(n_layers * r), skip_w) + skip_b, zero)
            s = np.maximum(dot(s, dec_w0) + dec_b0, zero)
            out = dot(s, dec_w1) + dec_b1
            if in_w.shape[0] > 0:
                out += dot(frames[t - 1, b], in_w) + in_b
            if residual:
                for i in range(mixtures):
                    out[mixtures + i * cont + kept] += frames[t - 1, b, kept]
            if outputs.shape[0] > 0:
                outputs[t, b] = out
            if teacher.shape[0] > 0:
                frames[t, b] = teacher[t, b]
                continue
            comp = _component.py_func(out, mixtures, float(unif[t, b]), temperature)
            mu0, ls0 = mixtures + comp * cont, mixtures + mixtures * cont + comp * cont
            sigma = np.zeros(cont, np.float32)
            for j, raw in zip(kept, (out[ls0 + kept] - min_log_sigma).tolist(), strict=True):
                soft = raw if raw > 20.0 else math.log1p(math.exp(raw))
                sigma[j] = math.exp(float(min_log_sigma) + soft)
            drawn = np.clip(out[mu0 : mu0 + cont] + sigma * temperature * eps[t, b], -DRAW_LIMIT, DRAW_LIMIT)
            frames[t, b, :cont] = np.where(modelled, drawn, 0.0)
            frames[t, b, cont:] = np.where(out[c0 : c0 + frames.shape[2] - cont] > 0.0, 1.0, 0.0)


KERNELS = (_generate,)  # what jit.pick chooses between, for the warm-up


class CachedSampler:
    """One step per frame: each layer keeps a queue of its inputs' contributions to frame t + dilation."""

    def __init__(self, model: TorchDanceNet | NumpyDanceNet) -> None:
        net = as_numpy(model)
        cfg = net.cfg
        self.cfg = cfg
        state = net.state

        def w(name: str) -> np.ndarray:
            return np.ascontiguousarray(state[f"{name}.weight"][:, :, -1].T, np.float32)

        def wk(name: str, tap: int) -> np.ndarray:
            return np.ascontiguousarray(state[f"{name}.weight"][:, :, tap].T, np.float64)

        def b(name: str, dtype: type = np.float64) -> np.ndarray:
            return state[f"{name}.bias"].astype(dtype)

        layers = [f"layers.{i}" for i in range(cfg.layers)]
        self.enc = [a for i in (0, 2, 4) for a in (w(f"motion_encoder.{i}"), b(f"motion_encoder.{i}", np.float32))]
        # Tap 1 of a kernel-2 dilated conv sees x[t], tap 0 sees x[t - d]. One matrix per layer gives both
        # this frame's filter|gate input and what this frame will contribute d frames later.
        self.w_np = np.stack([
            np.concatenate([wk(f"{n}.filter", 1), wk(f"{n}.gate", 1), wk(f"{n}.filter", 0), wk(f"{n}.gate", 0)], 1)
            for n in layers
        ], dtype=np.float32)  # fmt: skip
        # All layers' conditioning convs as one matrix: one matrix product per song gives every frame's input.
        self.cond_w = np.concatenate([wk(f"{n}.cond", 0) for n in layers], 1, dtype=np.float32)
        self.cond_b = np.concatenate(
            [np.concatenate([b(f"{n}.filter"), b(f"{n}.gate")]) + b(f"{n}.cond") for n in layers]
        ).astype(np.float32)
        self.w_res = np.stack([wk(f"{n}.res", 0) for n in layers], dtype=np.float32)
        self.b_res = np.stack([b(f"{n}.res") for n in layers]).astype(np.float32)
        self.skip_w = np.concatenate([wk(f"{n}.skip", 0) for n in layers], 0, dtype=np.float32)
        self.skip_b = np.sum([b(f"{n}.skip") for n in layers], axis=0).astype(np.float32)
        self.dec = [w("decoder.1"), b("decoder.1", np.float32), w("decoder.3"), b("decoder.3", np.float32)]
        self.input_skip = [w("input_skip"), b("input_skip", np.float32)] if cfg.input_skip else \
            [np.zeros((0, len(self.dec[3])), np.float32), np.zeros(len(self.dec[3]), np.float32)]
        self.modelled = state["modelled"].astype(np.bool_)
        self.dilations = np.array(cfg.dilations, dtype=np.int64)

    def layer_conditioning(self, cond: np.ndarray) -> np.ndarray:
        """Per frame and layer, the conditioning's contribution [T, L, 2R] (computed once per song)."""
        lc = np.asarray(cond, dtype=np.float32) @ self.cond_w + self.cond_b
        return lc.reshape(len(cond), self.cfg.layers, 2 * self.cfg.residual_channels)

    def run(
        self,
        first: np.ndarray,
        cond: np.ndarray,
        sampling: Sampling | None = None,
        teacher: np.ndarray | None = None,
        record_outputs: bool = False,
        progress: Progress | None = None,
        should_stop: Callable[[], bool] | None = None,
        prefix: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Generate len(cond) frames [B, T, D] from frame 0 `first` [B, D]; cond [T, C] conditions frame t.

        With `teacher` [B, T, D], frames come from it instead of sampling (outputs are then comparable
        with a teacher-forced forward pass). With `prefix` [B, K, D] (K >= 1, its frame 0 is `first`), frames
        before K are those and the rest is sampled after them: a dance continued from kept frames, which
        fill every layer's queue as if the model had danced them. Returns the frames and, if asked, the raw
        outputs [B, T, O].
        """
        cfg = self.cfg
        bsz, t_total, dim = len(first), len(cond), first.shape[1]
        frames = np.zeros((t_total, bsz, dim), np.float32)
        frames[0] = first
        out_dim = self.dec[3].shape[0]
        outputs = np.zeros((t_total if record_outputs else 0, bsz, out_dim), np.float32)
        queues = np.zeros((cfg.layers, max(cfg.dilations), bsz, 2 * cfg.residual_channels), np.float32)
        layer_cond = self.layer_conditioning(cond)
        tf = np.ascontiguousarray(teacher.transpose(1, 0, 2), dtype=np.float32) if teacher is not None \
            else np.zeros((0, bsz, dim), np.float32)
        kept = np.ascontiguousarray(prefix.transpose(1, 0, 2), dtype=np.float32) if prefix is not None \
            else np.zeros((0, bsz, dim), np.float32)
        rng = sampling.rng if sampling is not None else np.random.default_rng(0)
        temperature = sampling.temperature if sampling is not None else 1.0
        cont = cfg.continuous_dim
        generate = jit.pick(_generate, _generate_numpy)
        net = Net(self.dilations, *self.enc, self.w_np, self.w_res, self.b_res, self.skip_w, self.skip_b, *self.dec,
                  *self.input_skip, self.modelled)
        head = Head(cfg.mixtures, cont, np.float32(cfg.min_log_sigma), np.float32(temperature), cfg.residual_output)
        for t0 in range(1, t_total, CHUNK):
            t1 = min(t_total, t0 + CHUNK)
            # Draws for this chunk only (bounded memory), indexed by absolute frame.
            eps = np.zeros((t1, bsz, cont), np.float32)
            unif = np.zeros((t1, bsz), np.float32)
            if teacher is None:
                eps[t0:] = rng.standard_normal((t1 - t0, bsz, cont), dtype=np.float32)
                unif[t0:] = rng.random((t1 - t0, bsz), dtype=np.float32)
            split = min(max(t0, len(kept)), t1)  # frames before `split` are kept ones
            for a, b, forced in ((t0, split, kept), (split, t1, tf)):
                if a < b:
                    generate(Run(frames, outputs, queues, layer_cond, eps, unif, forced), net, head, a, b)
            if progress is not None:
                progress(t1 / t_total)
            if should_stop is not None and should_stop():
                raise InterruptedError("generation cancelled")
        return frames.transpose(1, 0, 2), (outputs.transpose(1, 0, 2) if record_outputs else None)

