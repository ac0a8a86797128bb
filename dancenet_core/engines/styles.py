"""The music style classifier, for any engine that dances in styles: the user's style, or the classifier's."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

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
