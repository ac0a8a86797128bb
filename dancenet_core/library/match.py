"""How well a figure fits a bar of music: a learned match of music and movement (`dancenet train match`), scored in
numpy at run time.

Both sides of a bar are read at `SAMPLES` points spread evenly over its beats, so that a figure and a bar meet on
their beats whatever their tempo (the plan warps figures onto the song's beats the same way):

- music: the onset, beat and downbeat activations at those points (where in the bar the accents fall), the bar's
  mean chroma and onset strength, its beat length and beats, for the bar and `context` bars either side (a bar
  alone says little of a style; its neighbours say more);
- motion: at those points, each body joint relative to the pelvis in the dancer's heading frame, each joint's speed
  and the pelvis' horizontal speed and height (where in the bar the dancer steps and holds), and the bar's beat
  length.

Two small networks (two layers each) map each side to a unit vector; trained contrastively on the paired capture
(each bar of music against the bar danced to it, the batch's other bars as negatives), the cosine of the two
vectors says how well the figure fits the bar. Weights are an `.npz` of plain arrays (`MatchModel.save`).
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..atomic import atomic_open
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from ..kinematics import fk_numpy
from ..music.features import BEAT_COL, CHROMA_COLS, DOWNBEAT_COL, ONSET_COL
from ..music.features import FPS as MUSIC_FPS
from ..skeleton import BODY_JOINTS, MIRROR_INDEX
from .store import MotionLibrary
from .transitions import beat_frames

MATCH_VERSION = "match-1"  # change whenever the bar features below change
MATCH_WEIGHTS = WEIGHTS_DIR / "match.npz"
SAMPLES = 12  # points per bar: 4 per beat of a 3/4 bar, 3 per beat of a 4/4 bar
LEFT_HIP, RIGHT_HIP = 1, 2
SPEED_SMOOTH_FRAMES = 1.0  # joint speeds lightly smoothed before sampling (25 fps capture)
_MIRROR = np.array(MIRROR_INDEX[:BODY_JOINTS])
FRAME_DIM = 3 * BODY_JOINTS + BODY_JOINTS + 2
SPEED_COLS = slice(3 * BODY_JOINTS, 4 * BODY_JOINTS)  # the joint speeds in `motion_frames`


def mirrored(positions: np.ndarray) -> np.ndarray:
    """Body positions [T, 22, 3] of the left/right mirror image (x negated, sides swapped)."""
    m = positions[:, _MIRROR].copy()
    m[..., 0] *= -1.0
    return m


def motion_frames(positions: np.ndarray, fps: float) -> np.ndarray:
    """[T, FRAME_DIM] per frame: body joints relative to the pelvis in the heading frame (the hips' line along x),
    each joint's speed (m/s, lightly smoothed), the pelvis' horizontal speed and height."""
    p = np.asarray(positions, np.float64)[:, :BODY_JOINTS]
    hips = p[:, LEFT_HIP] - p[:, RIGHT_HIP]
    yaw = np.arctan2(hips[:, 2], hips[:, 0])
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    rel = p - p[:, :1]
    local = np.stack([c * rel[..., 0] + s * rel[..., 2], rel[..., 1], -s * rel[..., 0] + c * rel[..., 2]], -1)
    vel = np.gradient(p, axis=0) * fps if len(p) > 1 else np.zeros_like(p)
    speed = gaussian_filter1d(np.linalg.norm(vel, axis=-1), SPEED_SMOOTH_FRAMES, axis=0)
    root = np.stack([np.linalg.norm(vel[:, 0, [0, 2]], axis=-1), p[:, 0, 1]], -1)
    return np.concatenate([local.reshape(len(p), -1), speed, root], 1).astype(np.float32)


def bar_points(beat_positions: np.ndarray) -> np.ndarray:
    """[N, SAMPLES] points evenly spread over each bar's beats: `beat_positions` [N, n + 1] are where its beats
    fall (frames or seconds, the last: the next bar's first beat); the points interpolate between them."""
    bp = np.asarray(beat_positions, np.float64)
    n = bp.shape[1] - 1
    u = np.arange(SAMPLES) / SAMPLES * n
    lo = np.minimum(np.floor(u).astype(np.int64), n - 1)
    a = u - lo
    return bp[:, lo] * (1.0 - a) + bp[:, lo + 1] * a


def _interp_rows(table: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Rows of `table` [T, D] at fractional indices `at` (any shape), linearly, clamped to the table."""
    at = np.clip(at, 0, len(table) - 1)
    lo = np.floor(at).astype(np.int64)
    hi = np.minimum(lo + 1, len(table) - 1)
    a = (at - lo)[..., None]
    return table[lo] * (1.0 - a) + table[hi] * a


def motion_bars(frames: np.ndarray, beat_frames: np.ndarray, fps: float) -> np.ndarray:
    """[N, SAMPLES * FRAME_DIM + 1]: each bar's motion (`motion_frames` rows) at its `bar_points`, and its mean beat
    length (log seconds); `beat_frames` [N, n + 1]: the bar's beats as (fractional) frames of `frames`."""
    pts = bar_points(beat_frames)
    x = _interp_rows(frames, pts).reshape(len(pts), -1)
    beat_s = (beat_frames[:, -1] - beat_frames[:, 0]) / (beat_frames.shape[1] - 1) / fps
    return np.concatenate([x, np.log(np.maximum(beat_s, 1e-3))[:, None]], 1).astype(np.float32)


def music_bars(features: np.ndarray, bar_beats: list[np.ndarray], context: int) -> np.ndarray:
    """[N, (2 context + 1) * per-bar dims]: each bar of music (its beats' times in seconds, the last: the next bar's
    first beat) from the song's features at MUSIC_FPS: the accents at its `bar_points`, its mean chroma and onset,
    its beat length and beat count, with `context` bars either side (the first and last bars repeated at the
    song's ends)."""
    rows = []
    for beats in bar_beats:
        t = bar_points(np.asarray(beats, np.float64)[None])[0]
        accents = _interp_rows(features[:, [ONSET_COL, BEAT_COL, DOWNBEAT_COL]], t * MUSIC_FPS).T.ravel()
        a, b = int(np.clip(beats[0] * MUSIC_FPS, 0, len(features) - 1)), int(beats[-1] * MUSIC_FPS)
        span = features[a : max(a + 1, b)]
        chroma = span[:, CHROMA_COLS].mean(0)
        n = len(beats) - 1
        rows.append(np.concatenate([accents, chroma, [span[:, ONSET_COL].mean(), np.log((beats[-1] - beats[0]) / n),
                                                      n]]))
    x = np.asarray(rows, np.float32).reshape(len(bar_beats), -1)
    if context == 0 or len(x) == 0:
        return x
    idx = np.clip(np.arange(len(x))[:, None] + np.arange(-context, context + 1)[None], 0, len(x) - 1)
    return x[idx].reshape(len(x), -1)


def _mlp(x: np.ndarray, layers: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    for k, (w, b) in enumerate(layers):
        x = x @ w.T + b
        if k < len(layers) - 1:
            x = np.maximum(x, 0.0)
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-9)


@dataclass
class MatchModel:
    """The two embedding networks (standardisation, then linear layers with ReLU between) and their settings."""

    music_mean: np.ndarray
    music_std: np.ndarray
    motion_mean: np.ndarray
    motion_std: np.ndarray
    music_layers: list[tuple[np.ndarray, np.ndarray]]
    motion_layers: list[tuple[np.ndarray, np.ndarray]]
    meta: dict
    style_layer: tuple[np.ndarray, np.ndarray] | None = None  # embedding -> the training styles' logits

    @property
    def context(self) -> int:
        return int(self.meta["context"])

    def embed_music(self, bars: np.ndarray) -> np.ndarray:
        """[N, E] unit vectors of `music_bars` rows."""
        return _mlp((bars - self.music_mean) / self.music_std, self.music_layers)

    def embed_motion(self, bars: np.ndarray) -> np.ndarray:
        """[N, E] unit vectors of `motion_bars` rows."""
        return _mlp((bars - self.motion_mean) / self.motion_std, self.motion_layers)

    def style_probs(self, embedded: np.ndarray) -> np.ndarray:
        """[N, styles] the training styles' probabilities of embedded bars (music or motion: one head for both)."""
        w, b = self.style_layer
        z = embedded @ w.T + b
        z = np.exp(z - z.max(axis=-1, keepdims=True))
        return z / z.sum(axis=-1, keepdims=True)

    def save(self, path: str | Path) -> None:
        arrays = {"music_mean": self.music_mean, "music_std": self.music_std, "motion_mean": self.motion_mean,
                  "motion_std": self.motion_std, "meta": np.array(json.dumps({**self.meta, "version": MATCH_VERSION}))}
        if self.style_layer is not None:
            arrays["style_w"], arrays["style_b"] = self.style_layer
        for side, layers in (("music", self.music_layers), ("motion", self.motion_layers)):
            for k, (w, b) in enumerate(layers):
                arrays[f"{side}_w{k}"], arrays[f"{side}_b{k}"] = w.astype(np.float16), b.astype(np.float32)
        with atomic_open(Path(path), "wb") as f:
            np.savez_compressed(f, **arrays)

    @classmethod
    def load(cls, path: str | Path = MATCH_WEIGHTS) -> MatchModel:
        """The weights written by `save`; a one-line error for a missing, damaged or other-version file."""
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("version") != MATCH_VERSION:
                    raise ValueError(f"weights of version {meta.get('version')}, this DanceNet reads {MATCH_VERSION}")

                def layers(side: str) -> list[tuple[np.ndarray, np.ndarray]]:
                    n = sum(1 for k in z.files if k.startswith(f"{side}_w"))
                    return [(z[f"{side}_w{k}"].astype(np.float32), z[f"{side}_b{k}"]) for k in range(n)]

                style = (z["style_w"], z["style_b"]) if "style_w" in z.files else None
                return cls(z["music_mean"], z["music_std"], z["motion_mean"], z["motion_std"], layers("music"),
                           layers("motion"), meta, style)
        except (OSError, KeyError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as e:
            raise DanceNetError(f"{path}: not match weights ({e}); reinstall DanceNet or retrain them "
                                "(dancenet train match)") from e


def library_frames(library: MotionLibrary) -> np.ndarray:
    """[N, FRAME_DIM]: `motion_frames` of every clip of the library, end to end as its frames are."""
    pos = fk_numpy(library.skeleton, library.rotations, library.root_positions, joints=BODY_JOINTS)[0]
    edges = library.clip_starts
    return np.concatenate([motion_frames(pos[a:b], library.fps) for a, b in zip(edges[:-1], edges[1:], strict=True)])


def frames_of(library: MotionLibrary) -> np.ndarray:
    """`library_frames`, from the library's build where it stored them (`MotionLibrary.match_frames`), else computed
    once and kept with the loaded library (a library built before they were stored)."""
    if library.match_frames is None:
        library.match_frames = library_frames(library)
    return library.match_frames


class FigureMatch:
    """How well each figure of a plan fits the song: on each bar, the cosine of the bar's music embedding and the
    embedding of the figure's motion over the clip beats the figure lays on that bar (`fit`); over the whole part,
    how much less probable the style of the figure's clip (the most probable of the training styles over its
    figures' motion) is than the most probable style of the part's music (the mean of its bars' probabilities;
    `style_away`): a bar alone often sounds like another style, the part seldom does, and a clip is danced in one
    style."""

    def __init__(self, model: MatchModel, library: MotionLibrary, features: np.ndarray,
                 bar_beats: list[np.ndarray]) -> None:
        self.model, self.library = model, library
        self.frames = frames_of(library)
        self.music = model.embed_music(music_bars(features, bar_beats, model.context))
        song = model.style_probs(self.music).mean(axis=0) if model.style_layer is not None else None
        self.song_style = None if song is None else song / song.max()  # its most probable style: 1
        self._motion: dict[tuple[int, bytes, bytes], np.ndarray] = {}

    def _embedded(self, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        """[F, E] each figure's motion over `beats` song beats (figures on bars of as many beats embedded once)."""
        key = (beats, starts.tobytes(), ratios.tobytes())
        if key not in self._motion:
            position = starts[:, None] + ratios[:, None] * np.arange(beats + 1)[None, :]
            frames = beat_frames(self.library, np.clip(position, 0, len(self.library.beats) - 1))
            self._motion[key] = self.model.embed_motion(motion_bars(self.frames, frames, self.library.fps))
        return self._motion[key]

    def fit(self, bar: int, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        """[F] cosine per figure on `bar`, whose `beats` song beats each figure (a start, a library beat, and clip
        beats per song beat) lays clip beats on evenly."""
        return self._embedded(starts, ratios, beats) @ self.music[bar]

    def style_away(self, starts: np.ndarray, ratios: np.ndarray, beats: int) -> np.ndarray:
        """[F] in [0, 1]: 1 less the part's probability of each figure's clip's style over its most probable's (0
        for weights without a style head)."""
        if self.song_style is None:
            return np.zeros(len(starts))
        return 1.0 - self.song_style[self._clip_styles(starts, self._embedded(starts, ratios, beats))]

    def _clip_styles(self, starts: np.ndarray, embedded: np.ndarray) -> np.ndarray:
        """[F]: the style of each figure's clip, the most probable over its figures (a style is the clip's, not a
        bar's: its figures share it, so that the plan keeps to the style and not to a clip's most typical bars)."""
        clip = self.library.beat_clip[np.floor(starts + 1e-6).astype(np.int64)]
        probs = self.model.style_probs(embedded)
        sums = np.stack([np.bincount(clip, probs[:, k], self.library.num_clips) for k in range(probs.shape[1])], 1)
        return sums.argmax(axis=1)[clip]
