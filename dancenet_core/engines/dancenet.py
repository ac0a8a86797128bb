"""DanceNet, the first engine: the music context encoder, cached autoregressive sampling of the mixture, the
Foot Constraint Model, decoded to Motions. Same request, same seed: the same dance, bit for bit."""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..constants import MIN_PART_S
from ..errors import DanceNetError, GenerationCancelled
from ..motion import Motion
from ..music.features import FEATURE_SPEC, FeatureSpec, MusicAnalysis, music_at_frames
from ..progress import Progress, StageProgress
from ..representation import FeatureLayout, decode, encode
from ..request import DanceRequest
from ..runtime.sampler import CachedSampler, Sampling, music_conditioning
from ..runtime.weights import DEFAULT_RUNTIME, RuntimeBundle, RuntimeFootFixer
from ..shaping.beatlock import lock_to_beats
from ..shaping.continuation import join_kept
from ..shaping.floor import floor_shift
from ..shaping.footlock import lock_feet, planted_feet
from . import Takes
from .styles import check_style, choose_style, is_checkpoint

if TYPE_CHECKING:
    from ..nets.bundle import DanceNetBundle

    # What generation runs: the runtime's arrays; training and evaluation pass their torch bundles too.
    Bundle = RuntimeBundle | DanceNetBundle

# Gaussian sigma in frames on the generated channels, chosen with the temperature on the validation songs.
OUTPUT_SMOOTHING_FRAMES = 1.5


@lru_cache(maxsize=2)
def load_bundle(path: str | None = None) -> RuntimeBundle:
    """The DanceNet weights as plain arrays: the shipped `.npz` by default; a training checkpoint (`.pt`, e.g.
    from `runs/`) is converted in memory, which needs torch. A one-line error for weights trained on other music
    features than these."""
    if is_checkpoint(path):
        from ..nets.bundle import DanceNetBundle  # torch: only where checkpoints are trained
        from ..nets.export import bundle_to_runtime

        bundle = bundle_to_runtime(DanceNetBundle.load(path))
    else:
        bundle = RuntimeBundle.load(path or DEFAULT_RUNTIME)
    FEATURE_SPEC.check_trained(FeatureSpec.from_dict(bundle.model.cfg.music_spec), "DanceNet weights")
    return bundle


@lru_cache(maxsize=2)
def foot_fixer(path: Path | None = None) -> RuntimeFootFixer:
    """The shipped Foot Constraint Model, or the one at `path` (a run's `footfix.npz`, for validation); loaded once."""
    return RuntimeFootFixer.load() if path is None else RuntimeFootFixer.load(path)


# Foot clean-ups (`clean_feet`): the Foot Constraint Model (a network over the lower body), the contact lock (two-bone
# IK on the legs, `footlock.py`), or the one then the other; the one generation uses was chosen on the validation
# songs (docs/training.md).
CLEANUPS = ("model", "lock", "model+lock")
FOOT_CLEANUP = "lock"


def clean_feet(bundle: Bundle, feats: np.ndarray, cleanup: str | None = FOOT_CLEANUP,
               footfix_weights: Path | None = None) -> np.ndarray:
    """Unnormalised features [T, D] -> the same standing on the floor, frame by frame, where its predicted contacts
    say (`floor.floor_shift`, with or without a clean-up), and its feet cleaned by `cleanup` (one of CLEANUPS; None:
    none). The contact lock holds the feet the model plants and those it leaves on the floor (`planted_feet`) and
    writes the legs' rotations back into the features, so a continued dance joins its kept frames the same way.
    `footfix_weights`: a foot model other than the shipped one."""
    if cleanup is not None and cleanup not in CLEANUPS:
        raise DanceNetError(f"unknown foot clean-up {cleanup!r}; choose from {', '.join(CLEANUPS)}")
    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    out = foot_fixer(footfix_weights)(feats) if cleanup in ("model", "model+lock") else feats.copy()
    contacts = out[:, layout.contacts]
    motion = decode(out, bundle.model.cfg.fps, bundle.skeleton)
    out[:, 1] += floor_shift(motion, contacts)
    if cleanup in ("lock", "model+lock"):
        motion.root_positions[:, 1] = out[:, 1]
        locked = lock_feet(motion, planted_feet(motion, contacts))
        out[:, layout.rotations] = locked.rotations[:, 1:].reshape(len(out), -1)
        # A leg that cannot reach its held foot lifts it: stand the locked dance on the floor once more.
        out[:, 1] += floor_shift(locked, contacts)
    return out


def lock_beats(bundle: Bundle, feats: np.ndarray, beats_s: np.ndarray, keep: int = 0) -> np.ndarray:
    """Unnormalised features [T, D] with the dance's beats moved onto the song's `beats_s` (seconds from its first
    frame; `beatlock.py`), its first `keep` frames as they are. Before the foot clean-up, which holds the warped
    dance's feet."""
    return lock_to_beats(feats, bundle.model.cfg.fps, bundle.skeleton, beats_s, keep)[0]


def sample_dance(bundle: Bundle, cond: np.ndarray, first: np.ndarray, sampling: Sampling,
                 progress: Progress | None = None, should_stop: Callable[[], bool] | None = None,
                 prefix: np.ndarray | None = None) -> list[np.ndarray]:
    """Sample frames for each take and return them unnormalised [T, D], lightly smoothed.

    Each frame's mixture draw adds independent noise; a Gaussian of one frame (40 ms at 25 fps; the
    authors smooth with sigma 1 at 60 fps) over the continuous channels takes that jitter out without
    blurring the steps. Contacts stay as predicted.
    """
    frames, _ = CachedSampler(bundle.model).run(first, cond, sampling, progress=progress, should_stop=should_stop,
                                                prefix=prefix)
    return [finish_frames(bundle, take) for take in frames]


def finish_frames(bundle: Bundle, frames: np.ndarray, smoothing: float = OUTPUT_SMOOTHING_FRAMES) -> np.ndarray:
    """Sampled normalised frames [T, D] -> unnormalised, continuous channels smoothed (see sample_dance);
    `smoothing` is the Gaussian's sigma in frames (0: none)."""
    cont = bundle.model.cfg.continuous_dim
    feats = bundle.normalizer.denormalize(frames)
    if smoothing > 0:
        feats[:, :cont] = gaussian_filter1d(feats[:, :cont], smoothing, axis=0, mode="nearest")
    return feats


def scale_moves(feats: np.ndarray, layout: FeatureLayout, scale: float) -> np.ndarray:
    """The dance's moves `scale` times as large (the energy preset, `DanceRequest.move_scale`): each joint's
    rotation, the root's height and tilt and the end effectors about the take's mean, the root's steps and turns
    about zero; contacts as predicted. Before the foot model, which then cleans the feet of the scaled dance."""
    if scale == 1.0:
        return feats
    out = feats.copy()
    root = layout.root.start
    about_mean = np.r_[[root + 1, root + 4, root + 5], np.arange(layout.rotations.start, layout.end_effectors.stop)]
    mean = out[:, about_mean].mean(axis=0)
    out[:, about_mean] = mean + scale * (out[:, about_mean] - mean)
    out[:, [root, root + 2, root + 3]] *= scale
    return out


def kept_frames(bundle: Bundle, kept: Motion, at_s: float, frames: int) -> np.ndarray:
    """The dance kept up to `at_s` seconds as the model's normalised frames [K, D] at its frame rate, or a
    one-line error when there is not enough of it before `at_s`, or of the song after."""
    fps = bundle.model.cfg.fps
    if kept.skeleton.names != bundle.skeleton.names:
        raise DanceNetError("only a DanceNet dance (its 55 joints) can be continued")
    if not (np.isfinite(at_s) and 1.5 / fps <= at_s <= kept.duration + 0.5 / fps):
        raise DanceNetError(f"the dance can be continued from {2 / fps:g} s to its end ({kept.duration:.2f} s), "
                            f"got {at_s}")
    kept = kept.resampled(fps)
    k = min(int(round(at_s * fps)), kept.num_frames)
    if frames - k < MIN_PART_S * fps:
        raise DanceNetError(f"continuing at {at_s:g} s leaves less than {MIN_PART_S:g} s of the part of the song "
                            f"to dance ({frames / fps:.1f} s)")
    return bundle.normalizer.normalize(encode(kept[:k]))


class DanceNetEngine:
    """The engine `dancenet` (the default): reads `request.weights` (a `.npz`, or a training `.pt` with torch)."""

    name = "dancenet"

    def styles(self, request: DanceRequest) -> list[str]:
        return load_bundle(request.weights).styles

    def check(self, request: DanceRequest) -> None:
        """Load the weights (and the foot model when asked), so a bad file or an unknown style is reported now."""
        check_style(request.style, self.styles(request))
        if request.footfix and FOOT_CLEANUP in ("model", "model+lock"):
            foot_fixer()

    def dance(self, request: DanceRequest, analysis: MusicAnalysis, progress: StageProgress,
              should_cancel: Callable[[], bool]) -> Takes:
        """The music encoder hears only the requested part, so the dance follows what is played. With
        `request.continue_from`, its first `at_s` seconds are kept and the model hears them as its own frames,
        so the join flows."""
        timings: dict[str, float] = {}
        t = time.perf_counter()
        bundle = load_bundle(request.weights)
        cfg = bundle.model.cfg
        chosen, probs = choose_style(request.style, analysis, bundle.styles)
        timings["style_s"] = time.perf_counter() - t

        t = time.perf_counter()
        start, end = request.part(analysis.duration_s)
        n = max(2, int(round((end - start) * cfg.fps)))
        music = music_at_frames(analysis.features, analysis.fps, start + np.arange(n) / cfg.fps)
        cond = music_conditioning(bundle.model, music, bundle.styles.index(chosen))
        rng = np.random.default_rng(request.seed)
        starts = bundle.start_frames[chosen]
        first = bundle.normalizer.normalize(starts[rng.integers(len(starts), size=request.takes)])
        prefix = None
        if request.continue_from is not None:
            prefix = np.repeat(kept_frames(bundle, request.continue_from, request.at_s, n)[None], request.takes,
                               axis=0)
            first = prefix[:, 0]
        timings["music_encoder_s"] = time.perf_counter() - t

        t = time.perf_counter()
        progress("dancing", 0.0)
        try:
            takes_feats = sample_dance(bundle, cond, first, Sampling(request.sampling_temperature, rng),
                                       progress=lambda f: progress("dancing", f), should_stop=should_cancel,
                                       prefix=prefix)
        except InterruptedError as e:
            raise GenerationCancelled from e
        timings["generation_s"] = time.perf_counter() - t

        layout = FeatureLayout.for_skeleton(bundle.skeleton)
        takes_feats = [scale_moves(f, layout, request.move_scale) for f in takes_feats]
        t = time.perf_counter()
        if request.beat_lock:
            progress("locking to the beats", 0.0)
            beats = analysis.beat_times - start
            keep = 0 if prefix is None else prefix.shape[1]
            takes_feats = [lock_beats(bundle, f, beats, keep) for f in takes_feats]
        timings["beat_lock_s"] = time.perf_counter() - t
        t = time.perf_counter()
        progress("cleaning feet" if request.footfix else "placing on the floor", 0.0)
        takes_feats = [clean_feet(bundle, f, FOOT_CLEANUP if request.footfix else None) for f in takes_feats]
        timings["footfix_s"] = time.perf_counter() - t
        t = time.perf_counter()
        if prefix is None:
            motions = [decode(f, cfg.fps, bundle.skeleton) for f in takes_feats]
        else:
            kept = request.continue_from.resampled(cfg.fps)
            motions = [join_kept(kept, f, prefix.shape[1], bundle.skeleton) for f in takes_feats]
        contacts = [f[:, layout.contacts] for f in takes_feats]
        timings["decode_s"] = time.perf_counter() - t
        parts = ["dancenet_weights", *(["style_classifier"] if probs else ["chosen_style"]),
                 *(["foot_model"] if request.footfix and FOOT_CLEANUP in ("model", "model+lock") else [])]
        return Takes(motions, chosen, probs, contacts, timings, parts=parts)
