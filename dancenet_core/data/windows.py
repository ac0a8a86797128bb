"""Training windows as in the paper's supplement: 8-s windows at a small stride, drawn with weights that
balance k-means clusters of the motion, with Gaussian noise on inputs and targets and a left/right
mirror augmentation that keeps the music.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.cluster import KMeans

from ..representation import FeatureLayout, Normalizer
from .build import PairedSequence


def cluster_features(pair: PairedSequence, start: int, window: int, layout: FeatureLayout) -> np.ndarray:
    """Joint-position description of a window: end effectors (heading frame) and root height, every 0.4 s."""
    m = pair.motion[start : start + window : 10]
    return np.concatenate([m[:, layout.end_effectors], m[:, 1:2]], axis=1).ravel()


@dataclass
class Batch:
    motion: np.ndarray  # [B, W, D] normalised, noisy input frames
    target: np.ndarray  # [B, W, D] normalised targets (frame t is predicted from frames < t)
    music: np.ndarray  # [B, W, 15]
    style: np.ndarray  # [B] style indices


class WindowSampler:
    """Cluster-balanced sliding windows over paired sequences."""

    def __init__(
        self,
        pairs: list[PairedSequence],
        normalizer: Normalizer,
        styles: list[str],
        layout: FeatureLayout,
        window: int = 200,
        stride: int = 3,
        clusters: int = 8,
        seed: int = 0,
    ) -> None:
        self.pairs = [p for p in pairs if len(p.motion) >= window]
        self.norm = normalizer
        self.style_index = {s: i for i, s in enumerate(styles)}
        self.layout = layout
        self.window = window
        self.index = np.array(
            [(i, s) for i, p in enumerate(self.pairs) for s in range(0, len(p.motion) - window + 1, stride)]
        )
        feats = np.stack([cluster_features(self.pairs[i], s, window, layout) for i, s in self.index])
        feats = (feats - feats.mean(0)) / (feats.std(0) + 1e-6)
        k = min(clusters, len(self.index))
        self.labels = KMeans(k, n_init=4, random_state=seed).fit_predict(feats)
        sizes = np.bincount(self.labels, minlength=k)
        w = 1.0 / sizes[self.labels]
        self.weights = w / w.sum()

    @property
    def cluster_sizes(self) -> np.ndarray:
        return np.bincount(self.labels)

    def batch(
        self,
        rng: np.random.Generator,
        size: int,
        input_noise: float = 0.04,
        target_noise: float = 0.01,
        mirror_prob: float = 0.5,
    ) -> Batch:
        picks = rng.choice(len(self.index), size=size, p=self.weights)
        motion, music, style = [], [], []
        for i, s in self.index[picks]:
            p = self.pairs[i]
            src = p.mirrored if rng.random() < mirror_prob else p.motion
            motion.append(src[s : s + self.window])
            music.append(p.music[s : s + self.window])
            style.append(self.style_index[p.style])
        x = self.norm.normalize(np.stack(motion))
        cont = self.layout.continuous
        noisy = x.copy()
        noisy[..., cont] += rng.normal(0, input_noise, noisy[..., cont].shape).astype(np.float32)
        target = x.copy()
        target[..., cont] += rng.normal(0, target_noise, target[..., cont].shape).astype(np.float32)
        return Batch(noisy, target, np.stack(music), np.array(style))

    def fixed_windows(self, count: int, seed: int = 1234) -> Batch:
        """A reproducible, noise-free set of windows (for test loss)."""
        rng = np.random.default_rng(seed)
        return self.batch(rng, count, input_noise=0.0, target_noise=0.0, mirror_prob=0.0)
