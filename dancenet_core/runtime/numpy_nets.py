"""The small networks a Generate Dance runs, in numpy: DanceNet's music conditioning, the music style
classifier and the Foot Constraint Model (its floor guard included), so that generation needs no torch.

Each reads a state dict of plain arrays under torch's own names, with every BatchNorm already folded into
the convolution before it (`fold_batchnorm`; `nets/export.py` writes them). The per-frame stack of
DanceNet runs in the numba sampler (`runtime/sampler.py`) from the same arrays.

No numba here, measured: each network is a few large matrix products (BLAS already) and, for the two with a
Bi-LSTM, a recurrence of 100-150 steps per batch of windows whose sigmoids and tanhs numpy runs vectorised;
a compiled scalar loop took half as long again (its per-element exp and tanh cost more than numpy's calls).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.special import expit

from ..skeleton import LOWER_BODY, TOE_ENDS, Skeleton

if TYPE_CHECKING:
    from .config import DanceNetConfig

Arrays = Mapping[str, np.ndarray]
BATCHNORM_EPS = 1e-5  # torch's default, which every BatchNorm here uses


def fold_batchnorm(state: Arrays, pairs: Sequence[tuple[str, str]], dtype: type = np.float32,
                   eps: float = BATCHNORM_EPS) -> dict[str, np.ndarray]:
    """`state` with each (conv, norm) pair's BatchNorm (running statistics, as in inference) folded into the
    conv's weight and bias, and the norm's entries dropped: inference then runs one operation, not two.
    `dtype` float64 keeps the folded values unrounded, for a network run in float64 (DanceNet's music encoder)."""
    out = dict(state)

    def pop(name: str) -> np.ndarray:  # every step of the fold in float64, rounded (if at all) once at the end
        return np.asarray(out.pop(name), np.float64)

    for conv, norm in pairs:
        scale = pop(f"{norm}.weight") / np.sqrt(pop(f"{norm}.running_var") + eps)
        mean, shift = pop(f"{norm}.running_mean"), pop(f"{norm}.bias")
        out.pop(f"{norm}.num_batches_tracked", None)
        w, b = pop(f"{conv}.weight"), pop(f"{conv}.bias")
        out[f"{conv}.weight"] = (w * scale.reshape(-1, *[1] * (w.ndim - 1))).astype(dtype)
        out[f"{conv}.bias"] = ((b - mean) * scale + shift).astype(dtype)
    return out


def linear(x: np.ndarray, state: Arrays, name: str) -> np.ndarray:
    """A torch Linear (or a 1x1 Conv1d) over the last axis."""
    w = state[f"{name}.weight"]
    return x @ w.reshape(len(w), -1).T + state[f"{name}.bias"]


def time_convs(x: np.ndarray, state: Arrays, names: Sequence[str], pad_end: bool, last_stride: int = 2
               ) -> np.ndarray:
    """Features [B, T, F] -> [B, T', C * F]: Conv2d layers with (2, 1) kernels along time over the features
    as a one-channel image (BatchNorm folded), each followed by ReLU, the last with stride 2, flattened as
    torch's `permute(0, 2, 1, 3)` does. `pad_end`: one zero frame appended before each layer (DanceNet's
    encoder keeps its length; the style classifier's convs do not pad). `last_stride` 1 gives the last layer
    at every frame (windows of a song then take every other one)."""
    h = x[..., None]  # [B, T, F, C]
    for k, name in enumerate(names):
        w, b = state[f"{name}.weight"][..., 0], state[f"{name}.bias"]  # [C_out, C_in, 2]
        stride = last_stride if k == len(names) - 1 else 1
        # Output t reads frames t (first tap) and t + 1 (second tap); each tap is one 2-D product (BLAS).
        first, second = h[:, ::stride], h[:, 1::stride]
        out = _channels(first, w[..., 0])
        out[:, : second.shape[1]] += _channels(second, w[..., 1])
        if not pad_end:  # no zero frame after the last: the last output would lack its second tap
            out = out[:, : second.shape[1]]
        out += b
        h = np.maximum(out, 0.0, out=out)
    return h.transpose(0, 1, 3, 2).reshape(*h.shape[:2], -1)


def _channels(h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """[..., C_in] @ [C_out, C_in].T as one contiguous 2-D product."""
    product = np.ascontiguousarray(h).reshape(-1, h.shape[-1]) @ np.ascontiguousarray(w.T)  # BLAS needs contiguous
    return product.reshape(*h.shape[:-1], len(w))


def bilstm(x: np.ndarray, state: Arrays, name: str) -> np.ndarray:
    """A one-layer bidirectional torch LSTM (batch first, gates i, f, g, o): [B, T, I] -> [B, T, 2H]."""
    return lstm_recurrence(lstm_input(x, state, name), state, name)


def lstm_input(x: np.ndarray, state: Arrays, name: str) -> np.ndarray:
    """The input's share of every gate of both directions, [..., 2, 4H]: one matrix product for all steps."""
    directions = ("", "_reverse")
    w_ih = np.concatenate([state[f"{name}.weight_ih_l0{d}"] for d in directions])
    bias = np.concatenate([state[f"{name}.bias_ih_l0{d}"] + state[f"{name}.bias_hh_l0{d}"] for d in directions])
    return (x @ w_ih.T + bias).reshape(*x.shape[:-1], 2, -1)


def lstm_recurrence(gates_x: np.ndarray, state: Arrays, name: str) -> np.ndarray:
    """Hidden states [B, T, 2H] from `lstm_input`'s [B, T, 2, 4H]: both directions in the same loop (the
    backward one on time-reversed input), halving the steps."""
    w_hh = np.stack([state[f"{name}.weight_hh_l0{d}"].T for d in ("", "_reverse")])  # [2, H, 4H]
    hidden = w_hh.shape[1]
    gates_x = np.ascontiguousarray(np.stack([gates_x[:, :, 0], gates_x[:, ::-1, 1]]).transpose(2, 0, 1, 3))
    h = np.zeros((2, gates_x.shape[2], hidden), gates_x.dtype)  # [direction, B, H]
    c = np.zeros_like(h)
    seq = np.empty((len(gates_x), *h.shape), gates_x.dtype)
    for t, gx in enumerate(gates_x):  # gx [2, B, 4H]
        gates = gx + h @ w_hh
        act = expit(gates)  # the g quarter is taken as tanh instead: one call rather than three
        c = act[..., hidden : 2 * hidden] * c + act[..., :hidden] * np.tanh(gates[..., 2 * hidden : 3 * hidden])
        h = act[..., 3 * hidden :] * np.tanh(c)
        seq[t] = h
    return np.concatenate([seq[:, 0].transpose(1, 0, 2), seq[::-1, 1].transpose(1, 0, 2)], axis=-1)


def interpolate_linear(x: np.ndarray, size: int) -> np.ndarray:
    """[B, T, C] -> [B, size, C] as torch's `F.interpolate(mode="linear", align_corners=False)` along T."""
    n = x.shape[1]
    src = np.maximum((np.arange(size) + 0.5) * (n / size) - 0.5, 0.0)
    i0 = np.minimum(src.astype(np.int64), n - 1)
    lam = (src - i0)[:, None].astype(x.dtype)
    return x[:, i0] * (1 - lam) + x[:, np.minimum(i0 + 1, n - 1)] * lam


class NumpyDanceNet:
    """DanceNet's generation-time weights as arrays: the music conditioning runs here, the gated stack in
    `sampler.CachedSampler`, which reads `state` the same way it reads a torch model's."""

    def __init__(self, cfg: DanceNetConfig, state: Arrays) -> None:
        self.cfg = cfg
        self.state = dict(state)
        # The conditioning's weights in float64, where it runs (see `conditioning`), converted once.
        self.encoder = {k: np.asarray(v, np.float64) for k, v in self.state.items()
                        if k.startswith(("music_encoder.", "style_embedding."))}

    def conditioning(self, music: np.ndarray, style: np.ndarray) -> np.ndarray:
        """music [B, T, music_dim] at the motion rate and style indices [B] -> music code + style embedding
        per frame [B, T, code + style_dim] (torch's `DanceNet.conditioning`, transposed), in float64: the
        sampler turns a float32 rounding of the code into centimetres of dance, so only a code computed in
        float64 and rounded once (`sampler.music_conditioning`) is the same whichever library computes it."""
        music, state = np.asarray(music, np.float64), self.encoder
        if self.cfg.music_encoder == "frame":
            code = linear(music, state, "music_encoder.out")
        else:
            h = time_convs(music, state, [f"music_encoder.convs.{k}" for k in range(3)], pad_end=True)
            h = linear(bilstm(h, state, "music_encoder.lstm"), state, "music_encoder.out")
            code = interpolate_linear(h, music.shape[1])
        emb = state["style_embedding.weight"][np.asarray(style)]
        return np.concatenate([code, np.broadcast_to(emb[:, None], (*code.shape[:2], emb.shape[1]))], axis=-1)


class NumpyStyleNet:
    """The music style classifier's network ("conv": temporal conv + Bi-LSTM + FC, or the FC "baseline")."""

    def __init__(self, arch: str, state: Arrays) -> None:
        self.arch = arch
        self.state = dict(state)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """[B, T, inputs] classifier input -> [B, styles] logits."""
        x = np.asarray(x, np.float32)
        return self._logits(lstm_input(self._frames(x, stride=2), self.state, "lstm"))

    def windows(self, x: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
        """Logits [W, styles] of the windows x[s : s + length] of one song's input [T, inputs]. Windows overlap
        (30 s every 5 s), so what is computed frame by frame (the convs, or the baseline's FC, and the LSTM's
        input share) runs once over the song; only the recurrences run per window."""
        step = 1 if self.arch == "baseline" else 2
        frames = lstm_input(self._frames(np.asarray(x, np.float32)[None], stride=1), self.state, "lstm")[0]
        count = length if step == 1 else (length - 4) // 2 + 1  # the convs' outputs of one window
        return self._logits(frames[np.asarray(starts)[:, None] + step * np.arange(count)])

    def _frames(self, x: np.ndarray, stride: int) -> np.ndarray:
        """[B, T, inputs] -> the per-frame layers' output [B, T', 32 x inputs] (the last conv at `stride`)."""
        if self.arch == "baseline":
            return np.maximum(linear(x, self.state, "fc_in.0"), 0.0)
        return time_convs(x, self.state, ["conv.0", "conv.3", "conv.6"], pad_end=False, last_stride=stride)

    def _logits(self, gates_x: np.ndarray) -> np.ndarray:
        return linear(lstm_recurrence(gates_x, self.state, "lstm").mean(axis=1), self.state, "fc")


class NumpyFootNet:
    """The Foot Constraint Model's three temporal convs (kernel 3, dilations 1, 3, 9, zero padded)."""

    DILATIONS = (1, 3, 9)

    def __init__(self, state: Arrays) -> None:
        self.state = dict(state)
        # Each conv as one [3 x in, out] matrix over its three taps side by side (contiguous, so BLAS runs it).
        self.layers = [(np.concatenate(list(state[f"net.{2 * k}.weight"].transpose(2, 1, 0))),
                        state[f"net.{2 * k}.bias"], d) for k, d in enumerate(self.DILATIONS)]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """[T, n_in] -> increment [T, n_out]."""
        h = np.asarray(x, np.float32)
        t = len(h)
        for k, (w, b, d) in enumerate(self.layers):
            p = np.pad(h, ((d, d), (0, 0)))
            h = np.concatenate([p[:t], p[d : d + t], p[2 * d : 2 * d + t]], axis=1) @ w + b
            if k < len(self.layers) - 1:
                h = np.maximum(h, 0.0)
        return h


def toe_heights(lower: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Heights [T, 2] of the toe ends above the floor from the unnormalised lower-body channels [T, L] (root
    dx, y, dz, dyaw, swing x, swing z, then the leg joints' rotation vectors), where `ToeKinematics` puts
    them: a turn about the vertical or a step along the floor moves no height, so only the root's swing and
    height and the legs' rotations count."""

    def matrices(rotvecs: np.ndarray) -> np.ndarray:
        return Rotation.from_rotvec(rotvecs).as_matrix()

    x = np.asarray(lower, np.float64)
    rot = {0: matrices(np.stack([x[:, 4], np.zeros(len(x)), x[:, 5]], -1))}
    pos = {0: np.zeros((len(x), 3))}
    for i, j in enumerate(LOWER_BODY[1:]):
        p = skeleton.parents[j]
        pos[j] = pos[p] + rot[p] @ skeleton.offsets[j]
        rot[j] = rot[p] @ matrices(x[:, 6 + 3 * i : 9 + 3 * i])
    feet = skeleton.end_site_parents()[list(TOE_ENDS)]
    ends = skeleton.end_site_offsets()[list(TOE_ENDS)]
    toes = np.stack([pos[f][:, 1] + (rot[f] @ e)[:, 1] for f, e in zip(feet, ends, strict=True)], -1)
    return toes + (x[:, 1] + skeleton.offsets[0][1])[:, None]
