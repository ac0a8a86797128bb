"""Trained checkpoints (torch) -> the plain arrays generation runs on without torch (`runtime/weights.py`).

Training writes each runtime file beside the checkpoint it saves; `dancenet weights export` redoes it for the
checkpoints in a folder (the shipped ones by default), e.g. after copying in new weights.
"""

from __future__ import annotations

from pathlib import Path

from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError
from ..runtime.numpy_nets import NumpyFootNet, NumpyStyleNet, fold_batchnorm
from ..runtime.weights import RuntimeBundle, RuntimeFootFixer, RuntimeStyleModel
from .bundle import DanceNetBundle
from .dancenet import DanceNet, numpy_state
from .footfix import FootFixer
from .style_torch import StyleModel


def bundle_to_runtime(bundle: DanceNetBundle) -> RuntimeBundle:
    if not isinstance(bundle.model, DanceNet):
        raise DanceNetError(f"only DanceNet runs without torch, not the {bundle.model.cfg.kind} baseline")
    return RuntimeBundle(bundle.model.to_numpy(), bundle.normalizer, bundle.skeleton, bundle.start_frames,
                         bundle.info)


def style_to_runtime(model: StyleModel) -> RuntimeStyleModel:
    state = numpy_state(model.net)
    if model.arch == "conv":  # nn.Sequential of conv, BatchNorm and ReLU, three times
        state = fold_batchnorm(state, [("conv.0", "conv.1"), ("conv.3", "conv.4"), ("conv.6", "conv.7")])
    return RuntimeStyleModel(NumpyStyleNet(model.arch, state), model.styles, model.config, model.full_meta())


def fixer_to_runtime(fixer: FootFixer) -> RuntimeFootFixer:
    return RuntimeFootFixer(NumpyFootNet(numpy_state(fixer.model)), fixer.norm, fixer.layout, fixer.skeleton)


def export_runtime(weights: Path = WEIGHTS_DIR) -> list[Path]:
    """Write the runtime file (`.npz`, same name) of each of the three checkpoints found in the folder `weights`
    (`dancenet.pt`, `style_classifier.pt`, `footfix.pt`); returns the files written."""
    written = []
    for name, load, convert in (("dancenet", DanceNetBundle.load, bundle_to_runtime),
                                ("style_classifier", StyleModel.load, style_to_runtime),
                                ("footfix", FootFixer.load, fixer_to_runtime)):
        checkpoint = weights / f"{name}.pt"
        if checkpoint.is_file():
            convert(load(checkpoint)).save(checkpoint.with_suffix(".npz"))
            written.append(checkpoint.with_suffix(".npz"))
    return written
