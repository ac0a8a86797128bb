"""Everything a first Generate Dance waits for that is not the song itself: the imports (madmom, scipy), the
numba kernels (compiled, or read from numba's on-disk cache) and the shipped weights. The Blender add-on runs
`warm_up` on a thread of its own when it is enabled, so the first click after installing does not spend its
time compiling (issue 27: 17-30 s from cold on the 2-core machine, 2.5 s once compiled).

The kernels are compiled by running the real code on a few seconds of noise and a few frames of silence, so
they get the argument types a real run gives them; nothing is written to the music cache."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path

import numpy as np

from .constants import DEFAULT_TEMPERATURE
from .engines.dancenet import foot_fixer, load_bundle, sample_dance
from .engines.styles import load_style_model
from .music import madmom_dbn, madmom_nets
from .music.audio import MADMOM_SAMPLE_RATE, Audio
from .music.features import N_FEATURES, analyze_audio
from .runtime.sampler import Sampling, music_conditioning

WARM_AUDIO_S = 3  # one block of the analysis: both networks, chroma and the beat tracker's decode
WARM_FRAMES = 8  # the sampler's kernel is the same for any length


def _analysis() -> None:
    """madmom's networks through the compiled loop, the downbeat tracker's compiled decode, chroma and mel."""
    noise = 0.1 * np.random.default_rng(0).standard_normal(WARM_AUDIO_S * MADMOM_SAMPLE_RATE)
    analyze_audio(Audio(noise.astype(np.float32), MADMOM_SAMPLE_RATE, MADMOM_SAMPLE_RATE, 1, Path("warm-up")),
                  workers=1)


def _dance() -> None:
    """The weights (kept by their loaders' caches for the real run), the sampler's kernel, the foot model."""
    bundle = load_bundle()
    load_style_model()
    cond = music_conditioning(bundle.model, np.zeros((WARM_FRAMES, N_FEATURES), np.float32), 0)
    first = bundle.normalizer.normalize(bundle.start_frames[bundle.styles[0]][:1])
    takes = sample_dance(bundle, cond, first, Sampling(DEFAULT_TEMPERATURE, np.random.default_rng(0)))
    foot_fixer()(takes[0])


def warm_up(cancelled: Callable[[], bool] = lambda: False, lock: AbstractContextManager | None = None) -> None:
    """Load or compile what a Generate Dance needs, checking `cancelled` between steps (a compile cannot be
    stopped midway, so each kernel is a step of its own), each step holding `lock`: a caller that runs real
    generations on other threads holds the same lock around them, so the two never race."""
    for step in (madmom_nets.load_compiled, madmom_dbn.load_compiled, _analysis, _dance):
        if cancelled():
            return
        with lock or contextlib.nullcontext():
            step()
