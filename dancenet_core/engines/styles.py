"""The style of a dance, for any engine that dances in styles: the user's style, or the music style classifier's, or
(in the commercial mode, which runs no classifier) the style whose dance-sport tempo and meter fit the song's."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import DanceNetError
from ..music.features import FEATURE_SPEC, MusicAnalysis
from ..runtime.weights import STYLE_RUNTIME, RuntimeStyleModel


def is_checkpoint(path: str | Path | None) -> bool:
    """A training checkpoint (`.pt`, torch) rather than the runtime's plain arrays (`.npz`)."""
    return path is not None and Path(path).suffix == ".pt"


@lru_cache(maxsize=2)
def load_style_model(path: str | None = None) -> RuntimeStyleModel:
    """The music style classifier: the shipped `.npz` by default; a training checkpoint (`.pt`) is converted in
    memory, which needs torch. A one-line error for weights trained on other music features than these."""
    if is_checkpoint(path):
        from ..nets.export import style_to_runtime  # torch: only where checkpoints are trained
        from ..nets.style_torch import StyleModel

        model = style_to_runtime(StyleModel.load(path))
    else:
        model = RuntimeStyleModel.load(path or STYLE_RUNTIME)
    FEATURE_SPEC.check_trained(model.music_spec, "style classifier weights")
    return model


def check_style(requested: str, styles: list[str]) -> None:
    """A one-line error for a style the engine does not dance."""
    if requested != "auto" and requested not in styles:
        raise DanceNetError(f"unknown style '{requested}'; choose auto or one of: {', '.join(styles)}")


def choose_style(requested: str, analysis: MusicAnalysis, styles: list[str]) -> tuple[str, dict[str, float]]:
    """The user's style, or the classifier's most probable style among `styles` (it reads the tracked beats as
    well as the features, hence the whole analysis), with the classifier's probabilities ({} for the user's)."""
    check_style(requested, styles)
    if requested != "auto":
        return requested, {}
    result = load_style_model().classify(analysis)
    probs = {s: float(p) for s, p in zip(result.styles, result.probabilities, strict=True)}
    known = {s: p for s, p in probs.items() if s in styles}
    if not known:
        raise DanceNetError("the style classifier knows none of the dance model's styles; pass --style")
    return max(known, key=known.get), probs


# The dance-sport tempi (WDSF and the ballroom associations' rules: bars per minute, times the beats of the bar),
# public facts: a style's tempo range in beats per minute and its beats to the bar.
DANCE_TEMPI: dict[str, tuple[float, float, int]] = {
    "waltz": (84, 90, 3), "viennesewaltz": (174, 180, 3), "tango": (124, 132, 4), "foxtrot": (112, 120, 4),
    "quickstep": (200, 208, 4), "chacha": (120, 128, 4), "rumba": (100, 108, 4), "samba": (96, 104, 4),
    "pasodoble": (120, 124, 4), "jive": (168, 176, 4), "salsa": (160, 220, 4), "bachata": (120, 144, 4),
    "swing": (120, 200, 4), "hiphop": (80, 115, 4), "house": (118, 130, 4),
}
TEMPO_SLACK = 0.05  # a recording a little off its style's range still reads as that style


def style_by_tempo(tempo_bpm: float, meter: int, styles: list[str]) -> str:
    """The style of `styles` whose dance-sport tempo range (`DANCE_TEMPI`, widened by `TEMPO_SLACK`) and meter fit
    the song's, the nearest range's centre first; "" when none does (a style of another name is never guessed)."""
    fits = []
    for style in styles:
        known = DANCE_TEMPI.get("".join(c for c in style.lower() if c.isalnum()))
        if known is None:
            continue
        low, high, beats = known
        if beats == meter and low * (1 - TEMPO_SLACK) <= tempo_bpm <= high * (1 + TEMPO_SLACK):
            fits.append((abs(tempo_bpm - (low + high) / 2) / (high - low + 1), style))
    return min(fits)[1] if fits else ""


def meter_of(analysis: MusicAnalysis) -> int:
    """Beats to the bar: the most common count of beats between downbeats (4 without two downbeats)."""
    bars = np.diff(np.flatnonzero(np.isin(analysis.beat_times, analysis.downbeat_times)))
    return int(np.bincount(bars).argmax()) if len(bars) else 4
