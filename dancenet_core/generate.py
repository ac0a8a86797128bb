"""Song -> dance: the one entry point the command line, the Blender add-on and batch mode share.

Stages: analyse the music (cached), pick the style (the classifier, or the user's choice), encode the
music context, sample DanceNet frame by frame, decode to a Motion, and clean the feet.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .constants import DEFAULT_TEMPERATURE, MAX_TEMPERATURE
from .continuation import join_kept
from .errors import DanceNetError
from .model.runtime import DEFAULT_RUNTIME, STYLE_RUNTIME, RuntimeBundle, RuntimeFootFixer, RuntimeStyleModel
from .model.sampler import CachedSampler, Sampling, music_conditioning
from .motion import Motion
from .music.features import FPS as MUSIC_FPS
from .music.features import MusicAnalysis, analyze_music, music_at_frames
from .progress import Progress, StageProgress
from .representation import FeatureLayout, decode, encode

if TYPE_CHECKING:
    from .nets.bundle import DanceNetBundle

    # What generation runs: the runtime's arrays; training and evaluation pass their torch bundles too.
    Bundle = RuntimeBundle | DanceNetBundle

MAX_SEED = 2**32 - 1
MAX_TAKES = 100
# The shortest part of a song worth dancing (a bar at 60 BPM is 4 s; one second still shows a move).
MIN_PART_S = 1.0
# Gaussian sigma in frames on the generated channels, chosen with the temperature on the validation songs.
OUTPUT_SMOOTHING_FRAMES = 1.5


class GenerationCancelled(Exception):
    """The user cancelled; nothing was produced."""


@dataclass
class GenerationResult:
    motions: list[Motion]
    beat_times: np.ndarray
    downbeat_times: np.ndarray
    tempo_bpm: float
    duration_s: float
    style: str
    style_probabilities: dict[str, float]
    timings: dict[str, float] = field(default_factory=dict)
    contacts: list[np.ndarray] = field(default_factory=list)  # [T, 2] predicted foot contacts per take
    start_s: float = 0.0  # where the dance starts in the song; beat times count from there


def _is_checkpoint(path: str | Path | None) -> bool:
    """A training checkpoint (`.pt`, torch) rather than the runtime's plain arrays (`.npz`)."""
    return path is not None and Path(path).suffix == ".pt"


@lru_cache(maxsize=2)
def load_bundle(path: str | None = None) -> RuntimeBundle:
    """The DanceNet weights as plain arrays: the shipped `.npz` by default; a training checkpoint (`.pt`, e.g.
    from `runs/`) is converted in memory, which needs torch."""
    if _is_checkpoint(path):
        from .nets.bundle import DanceNetBundle  # torch: only where checkpoints are trained
        from .nets.export import bundle_to_runtime

        return bundle_to_runtime(DanceNetBundle.load(path))
    return RuntimeBundle.load(path or DEFAULT_RUNTIME)


@lru_cache(maxsize=2)
def load_style_model(path: str | None = None) -> RuntimeStyleModel:
    """The music style classifier: the shipped `.npz` by default; a checkpoint (`.pt`) as for `load_bundle`."""
    if _is_checkpoint(path):
        from .nets.export import style_to_runtime  # torch: only where checkpoints are trained
        from .nets.style_torch import StyleModel

        return style_to_runtime(StyleModel.load(path))
    return RuntimeStyleModel.load(path or STYLE_RUNTIME)


@lru_cache(maxsize=1)
def foot_fixer() -> RuntimeFootFixer:
    """The shipped Foot Constraint Model (loaded once)."""
    return RuntimeFootFixer.load()


def available_styles(weights: str | None = None) -> list[str]:
    """The styles the shipped model dances, from its metadata."""
    return load_bundle(weights).styles


def choose_style(
    requested: str, analysis: MusicAnalysis, styles: list[str]
) -> tuple[str, dict[str, float]]:
    """The user's style, or the classifier's most probable style among those the dance model knows (it reads
    the tracked beats as well as the features, hence the whole analysis)."""
    if requested != "auto":
        if requested not in styles:
            raise DanceNetError(f"unknown style '{requested}'; choose auto or one of: {', '.join(styles)}")
        return requested, {}
    result = load_style_model().classify(analysis)
    probs = {s: float(p) for s, p in zip(result.styles, result.probabilities, strict=True)}
    known = {s: p for s, p in probs.items() if s in styles}
    if not known:
        raise DanceNetError("the style classifier knows none of the dance model's styles; pass --style")
    return max(known, key=known.get), probs


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


def check_part(start_s: float, end_s: float | None) -> None:
    """Reject a part of the song that cannot exist whatever the song (before the music is analysed)."""
    if not (np.isfinite(start_s) and start_s >= 0):
        raise DanceNetError(f"start must be 0 or more seconds into the song, got {start_s}")
    if end_s is not None and not (np.isfinite(end_s) and end_s >= start_s + MIN_PART_S):
        raise DanceNetError(f"end ({end_s} s) must be at least {MIN_PART_S:g} s after start ({start_s} s)")


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


def song_part(duration_s: float, start_s: float, end_s: float | None) -> tuple[float, float]:
    """(start, end) seconds of the part to dance: the end is clipped to the song's; a start too close to the
    song's end is an error that says how long the song is."""
    end = duration_s if end_s is None else min(end_s, duration_s)
    if end - start_s < MIN_PART_S:
        raise DanceNetError(f"start {start_s:g} s leaves less than {MIN_PART_S:g} s of the song to dance "
                            f"(the song lasts {duration_s:.1f} s)")
    return start_s, end


def check_song_path(song: str | Path) -> Path:
    """`song` as a Path if it names a file; a one-line error saying what it is otherwise."""
    path = Path(song)
    if path.is_dir():
        raise DanceNetError(f"{song} is a folder, not an audio file; give the path of a song file")
    if not path.is_file():
        raise DanceNetError(f"song not found: {song} (check the path)")
    return path


def check_request(song: str | Path, style: str, seed: int, temperature: float, takes: int, footfix: bool,
                  weights: str | None, start_s: float = 0.0, end_s: float | None = None) -> None:
    """Reject bad arguments in a second, before a minute of music analysis: loads the weights (and the foot
    model when asked) so a bad file or an unknown style is reported now."""
    check_part(start_s, end_s)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed <= MAX_SEED:
        raise DanceNetError(f"seed must be a whole number from 0 to {MAX_SEED}, got {seed}")
    if not 0 <= temperature <= MAX_TEMPERATURE:  # also false for NaN
        raise DanceNetError(f"temperature must be from 0 to {MAX_TEMPERATURE:g} (0 = the most likely dance, "
                            f"default {DEFAULT_TEMPERATURE:g}), got {temperature}")
    if not 1 <= takes <= MAX_TAKES:
        raise DanceNetError(f"takes must be from 1 to {MAX_TAKES}, got {takes}")
    check_song_path(song)
    styles = load_bundle(weights).styles
    if style != "auto" and style not in styles:
        raise DanceNetError(f"unknown style '{style}'; choose auto or one of: {', '.join(styles)}")
    if footfix:
        foot_fixer()


def generate_dance(
    song: str | Path,
    style: str = "auto",
    seed: int = 0,
    temperature: float = DEFAULT_TEMPERATURE,
    takes: int = 1,
    footfix: bool = True,
    progress: StageProgress | None = None,
    should_cancel: Callable[[], bool] | None = None,
    weights: str | None = None,
    start_s: float = 0.0,
    end_s: float | None = None,
    continue_from: Motion | None = None,
    at_s: float = 0.0,
) -> GenerationResult:
    """Generate `takes` dances for a song, or for its part from `start_s` to `end_s` seconds (the music
    encoder then hears only that part, so the dance follows what is played). With `continue_from` (a dance
    to that part), its first `at_s` seconds are kept and the rest is danced anew after them: the model
    hears the kept frames as its own, so the join flows. Same arguments, same seed: the same dance, bit
    for bit."""
    check_request(song, style, seed, temperature, takes, footfix, weights, start_s, end_s)
    report = progress or (lambda _s, _f: None)
    cancelled = should_cancel or (lambda: False)
    timings: dict[str, float] = {}

    t = time.perf_counter()
    report("analysing music", 0.0)
    analysis = analyze_music(song, progress=lambda f: report("analysing music", f))
    timings["analysis_s"] = time.perf_counter() - t
    if cancelled():
        raise GenerationCancelled

    t = time.perf_counter()
    bundle = load_bundle(weights)
    cfg = bundle.model.cfg
    chosen, probs = choose_style(style, analysis, bundle.styles)
    timings["style_s"] = time.perf_counter() - t

    t = time.perf_counter()
    start, end = song_part(analysis.duration_s, start_s, end_s)
    n = max(2, int(round((end - start) * cfg.fps)))
    music = music_at_frames(analysis.features, MUSIC_FPS, start + np.arange(n) / cfg.fps)
    cond = music_conditioning(bundle.model, music, bundle.styles.index(chosen))
    rng = np.random.default_rng(seed)
    starts = bundle.start_frames[chosen]
    first = bundle.normalizer.normalize(starts[rng.integers(len(starts), size=takes)])
    prefix = None
    if continue_from is not None:
        prefix = np.repeat(kept_frames(bundle, continue_from, at_s, n)[None], takes, axis=0)
        first = prefix[:, 0]
    timings["music_encoder_s"] = time.perf_counter() - t

    t = time.perf_counter()
    report("dancing", 0.0)
    try:
        takes_feats = sample_dance(bundle, cond, first, Sampling(temperature, rng),
                                   progress=lambda f: report("dancing", f), should_stop=cancelled, prefix=prefix)
    except InterruptedError as e:
        raise GenerationCancelled from e
    timings["generation_s"] = time.perf_counter() - t

    layout = FeatureLayout.for_skeleton(bundle.skeleton)
    if footfix:
        t = time.perf_counter()
        report("cleaning feet", 0.0)
        fixer = foot_fixer()
        takes_feats = [fixer(f) for f in takes_feats]
        timings["footfix_s"] = time.perf_counter() - t
    t = time.perf_counter()
    if prefix is None:
        motions = [decode(f, cfg.fps, bundle.skeleton) for f in takes_feats]
    else:
        kept = continue_from.resampled(cfg.fps)
        motions = [join_kept(kept, f, prefix.shape[1], bundle.skeleton) for f in takes_feats]
    contacts = [f[:, layout.contacts] for f in takes_feats]
    timings["decode_s"] = time.perf_counter() - t
    report("done", 1.0)
    def within(times: np.ndarray) -> np.ndarray:
        return times[(times >= start) & (times < end)] - start

    return GenerationResult(
        motions=motions, beat_times=within(analysis.beat_times), downbeat_times=within(analysis.downbeat_times),
        tempo_bpm=analysis.tempo_bpm, duration_s=end - start, style=chosen,
        style_probabilities=probs, timings=timings, contacts=contacts, start_s=start,
    )
