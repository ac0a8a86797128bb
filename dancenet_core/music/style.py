"""Musical style classifier (paper section 4.2) and its FC + Bi-LSTM baseline: inference without torch (the
numpy network is `runtime/numpy_nets.py`, the torch one `nets/style_torch.py`, training `training/style.py`).

The classifier sees 30-second windows of a song's [T, 17] classifier input (10 fps; `classifier_input`) as a
one-channel image:
three Conv2d layers with (2, 1) kernels along time, channels 1-16-24-32 (the last with stride 2, as in the
authors' music encoder), BatchNorm and ReLU, then a Bi-LSTM over time and a fully connected layer on its
time-averaged output. A song's style is the mean of its windows' probabilities. Style names live in the
checkpoint's metadata, never in code, so a model trained on other styles needs no code change.

The classifier input is the music features with the beat and downbeat activation columns replaced by a bump of
fixed height at each beat and downbeat that madmom's DBN tracked: sampled at 10 fps, the 100-fps activations
miss many of their peaks (a song's highest sampled beat value ranges 0.24-0.93 on the training songs), while
the tracked beats carry tempo and metre (3 beats a bar for waltz) intact. Two more columns spell the metre and
tempo out (`meter_tempo`): from bumps alone the net had to count beats between downbeats and measure their
spacing over a 30-s window, and it called held-out waltzes rumba and cha-cha tango. DanceNet's own input is
unchanged.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.special import softmax

from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from .features import BEAT_COL, DOWNBEAT_COL, FPS, N_FEATURES, FeatureSpec, MusicAnalysis

DEFAULT_WEIGHTS = WEIGHTS_DIR / "style_classifier.pt"
BASELINE_WEIGHTS = WEIGHTS_DIR / "style_baseline.pt"
# 2: beat and downbeat columns are DBN bumps (`classifier_input`). Loading reads off the weights how many of its
# columns the network takes (`weights_inputs`), so weights from before the metre and tempo columns still run.
CHECKPOINT_FORMAT = "dancenet-style-2"

WINDOW_S = 30.0  # the paper's window: style is not decided by a 2-3 s clip

HOP_S = 5.0  # between windows when a whole song is classified

ARCHS = ("conv", "baseline")
# Network sizes chosen on training songs held out by song (`dancenet train style --validate`), never on the test split.
HIDDEN = 32

DROPOUT = 0.3
# The classifier input's columns after the 15 music features: beats in the bar minus 3, log2(tempo / 120 bpm).
METER_COL, TEMPO_COL = N_FEATURES, N_FEATURES + 1
N_INPUTS = N_FEATURES + 2
TEMPO_REF_BPM = 120.0  # the ballroom tempos here (70-190 bpm) land in [-0.8, 0.7], the scale of the other columns
TEMPO_MEDIAN_BEATS = 5  # the local tempo is the median of this many beat intervals: one mistracked beat moves none

# Bump width: a beat between two frames still shows at exp(-1/8) = 0.88, and bumps of the fastest songs
# (190 bpm, 3.2 frames apart) dip to 0.28 between beats.
BUMP_SIGMA_FRAMES = 1.0


def bump_track(positions: np.ndarray, num_frames: int) -> np.ndarray:
    """[num_frames] float32 with a Gaussian bump of height 1 at each (fractional) frame position, overlapping
    bumps joined by their maximum: every beat shows at nearly full height, whatever the frame grid."""
    p = np.concatenate([[-np.inf], np.sort(np.asarray(positions, np.float64)), [np.inf]])
    grid = np.arange(num_frames, dtype=np.float64)
    i = np.searchsorted(p, grid)
    nearest = np.minimum(grid - p[i - 1], p[i] - grid)
    return np.exp(-0.5 * (nearest / BUMP_SIGMA_FRAMES) ** 2).astype(np.float32)

def meter_tempo(beats: np.ndarray, downbeats: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    """[num_frames, 2] float32 from tracked beat and downbeat positions (fractional frames): the number of beats
    in the bar each frame lies in, minus 3 (0 for 3/4, 1 for 4/4; clipped to 2-5 beats, as a gap in the
    tracking makes one long bar), and the local tempo as log2(bpm / TEMPO_REF_BPM), clipped to 30-480 bpm.
    Frames before the first bar or beat take its value, those after the last the last's; a column stays 0
    where the tracker found fewer than two downbeats or beats."""
    out = np.zeros((num_frames, 2), np.float32)
    grid = np.arange(num_frames)
    beats, downbeats = np.sort(beats), np.sort(downbeats)
    if len(downbeats) >= 2:
        per_bar = np.diff(np.searchsorted(beats, downbeats - 0.5))  # each downbeat is a tracked beat
        bar = np.clip(np.searchsorted(downbeats, grid, side="right") - 1, 0, len(per_bar) - 1)
        out[:, 0] = np.clip(per_bar[bar], 2, 5) - 3
    if len(beats) >= 2:
        intervals = np.diff(beats)
        k = min(TEMPO_MEDIAN_BEATS, len(intervals))
        padded = np.pad(intervals, (k // 2, k - 1 - k // 2), mode="edge")
        local = np.median(sliding_window_view(padded, k), axis=1)
        at = np.clip(np.searchsorted(beats, grid, side="right") - 1, 0, len(local) - 1)
        bpm = 60.0 * fps / np.maximum(local[at], 1e-6)
        out[:, 1] = np.clip(np.log2(bpm / TEMPO_REF_BPM), -2.0, 2.0)
    return out

def draw_rhythm(x: np.ndarray, beats: np.ndarray, downbeats: np.ndarray, fps: float) -> np.ndarray:
    """Fill the columns of a classifier input [T, N_INPUTS] that come from the tracked beats and downbeats
    (positions in frames at `fps`): their bumps, beats per bar and tempo; returns `x`. Training's augmentation
    calls it with moved beats, so all four columns follow a change of tempo alike."""
    x[:, BEAT_COL] = bump_track(beats, len(x))
    x[:, DOWNBEAT_COL] = bump_track(downbeats, len(x))
    x[:, N_FEATURES:] = meter_tempo(beats, downbeats, len(x), fps)
    return x

def classifier_input(analysis: MusicAnalysis) -> np.ndarray:
    """[T, N_INPUTS] input of the style classifier: the music features, with the beat and downbeat activations
    replaced by bumps at the DBN's beat and downbeat times, then beats per bar and tempo (the module docstring
    says why)."""
    x = np.zeros((analysis.num_frames, N_INPUTS), np.float32)
    x[:, :N_FEATURES] = analysis.features
    fps = analysis.fps
    return draw_rhythm(x, analysis.beat_times * fps, analysis.downbeat_times * fps, fps)

def weights_inputs(state: Mapping[str, Any], config: dict) -> dict:
    """`config` with "inputs", the classifier input columns that a style network's weights read (the Bi-LSTM
    takes 32 numbers per column in both architectures): a file does not have to say it."""
    return {**config, "inputs": int(state["lstm.weight_ih_l0"].shape[1]) // 32}

def window_starts(num_frames: int, window: int, hop: int) -> np.ndarray:
    """Starts of windows every `hop` frames, plus one flush with the end so the tail counts too;
    a song shorter than a window is one shorter window."""
    if num_frames <= window:
        return np.zeros(1, dtype=np.int64)
    starts = np.arange(0, num_frames - window + 1, hop)
    if starts[-1] != num_frames - window:
        starts = np.append(starts, num_frames - window)
    return starts

@dataclass
class StyleResult:
    """A song's style: mean window probabilities, and each window's own."""

    styles: tuple[str, ...]
    probabilities: np.ndarray  # [S]
    window_starts_s: np.ndarray  # [W]
    window_probabilities: np.ndarray  # [W, S]
    window_s: float

    @property
    def style(self) -> str:
        return self.styles[int(np.argmax(self.probabilities))]

    def window_styles(self) -> list[str]:
        return [self.styles[int(i)] for i in np.argmax(self.window_probabilities, axis=1)]

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "style": self.style,
            "probabilities": {s: round(float(p), 4) for s, p in zip(self.styles, self.probabilities, strict=True)},
            "window_s": self.window_s,
            "windows": [
                {
                    "start_s": round(float(t), 2),
                    "style": s,
                    "probabilities": {n: round(float(p), 4) for n, p in zip(self.styles, probs, strict=True)},
                }
                for t, s, probs in zip(
                    self.window_starts_s, self.window_styles(), self.window_probabilities, strict=True
                )
            ],
        }

class StyleClassifier(ABC):
    """What every style classifier shares, whatever runs its network (numpy at generation, `nets/style_torch.py`'s
    torch in training): style names, window, hop and frame rate, and a song classified window by window."""

    def __init__(self, styles: Sequence[str], config: dict, meta: dict | None = None) -> None:
        self.styles = tuple(styles)
        self.config = dict(config)
        self.meta = dict(meta or {})
        # Input columns the network reads: weights from before the metre and tempo columns read the first 15.
        self.inputs = int(self.config.get("inputs", N_INPUTS))
        self.fps = int(self.meta.get("fps", FPS))
        self.window = int(round(float(self.meta.get("window_s", WINDOW_S)) * self.fps))
        self.hop = int(round(float(self.meta.get("hop_s", HOP_S)) * self.fps))
        self.music_spec = FeatureSpec.from_dict(self.meta.get("music_spec"))  # the features it was trained on

    @abstractmethod
    def logits(self, x: np.ndarray) -> np.ndarray:
        """[B, T, inputs] classifier input -> [B, styles] logits."""

    def full_meta(self) -> dict:
        """The metadata a saved classifier carries: windows and the music features it was trained on."""
        return {**self.meta, "fps": self.fps, "window_s": self.window / self.fps, "hop_s": self.hop / self.fps,
                "feature_version": self.music_spec.version, "music_spec": self.music_spec.to_dict()}

    def window_probabilities(self, features: np.ndarray, starts: np.ndarray, batch: int = 64) -> np.ndarray:
        """[W, S] softmax of the windows of `features` starting at `starts`."""
        length = min(self.window, len(features))
        x = np.asarray(features, np.float32)
        return softmax(np.concatenate([self.logits(np.stack([x[s : s + length] for s in starts[i : i + batch]]))
                                       for i in range(0, len(starts), batch)]), axis=1)

    def classify(self, analysis: MusicAnalysis) -> StyleResult:
        """Style of a whole song from its analysis (features and tracked beats): mean of the windows'
        probabilities (an overconfident window counts at most 1, where in a mean of log-probabilities it could
        veto a style)."""
        features = analysis.features
        if analysis.fps != self.fps or features.ndim != 2 or features.shape[1] != N_FEATURES:
            raise ValueError(
                f"expected [T, {N_FEATURES}] features at {self.fps} fps, got {features.shape} at {analysis.fps}"
            )
        if len(features) < 4:
            raise DanceNetError("the song is too short to classify its style; give at least a few seconds")
        starts = window_starts(len(features), self.window, self.hop)
        probs = self.window_probabilities(classifier_input(analysis)[:, : self.inputs], starts)
        return StyleResult(
            self.styles,
            probs.mean(axis=0),
            starts / self.fps,
            probs,
            min(self.window, len(features)) / self.fps,
        )
