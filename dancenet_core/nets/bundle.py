"""A trained DanceNet with everything generation needs: config, weights, normaliser, styles, start
frames and the skeleton its dances are decoded onto. One file, shipped in `dancenet_core/weights/`.
The comparison's baselines (`nets/variants.py`) are saved the same way, with their `kind`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..checkpoint import load_weights, save_weights
from ..environment import WEIGHTS_DIR
from ..errors import DanceNetError, first_line
from ..representation import Normalizer
from ..skeleton import Skeleton
from .dancenet import DanceNet
from .variants import model_from_config

DEFAULT_BUNDLE = WEIGHTS_DIR / "dancenet.pt"


@dataclass
class DanceNetBundle:
    model: torch.nn.Module  # DanceNet (or a comparison baseline)
    normalizer: Normalizer
    skeleton: Skeleton
    start_frames: dict[str, np.ndarray]  # per style: [N, D] real first frames (unnormalised)
    info: dict = field(default_factory=dict)  # training facts for the model card

    @property
    def styles(self) -> list[str]:
        return list(self.model.cfg.styles)

    def to_dict(self) -> dict:
        return {
            "kind": "dancenet" if isinstance(self.model, DanceNet) else self.model.cfg.kind,
            "config": self.model.cfg.to_dict(),
            "state_dict": self.model.state_dict(),
            "normalizer": {"mean": self.normalizer.mean, "std": self.normalizer.std,
                           "constant": self.normalizer.constant},
            "skeleton_offsets": self.skeleton.offsets,
            "start_frames": self.start_frames,
            "info": self.info,
        }

    def save(self, path: str | Path) -> None:
        """Plain tensors and lists only (see checkpoint.py), written atomically."""
        save_weights(self.to_dict(), path)

    @classmethod
    def from_dict(cls, d: dict) -> DanceNetBundle:
        model = model_from_config(d.get("kind", "dancenet"), d["config"])
        model.load_state_dict(d["state_dict"])
        model.eval()
        n = d["normalizer"]
        return cls(model, Normalizer(np.asarray(n["mean"]), np.asarray(n["std"]), np.asarray(n["constant"])),
                   Skeleton(np.asarray(d["skeleton_offsets"])),
                   {k: np.asarray(v) for k, v in d["start_frames"].items()}, dict(d["info"]))

    @classmethod
    def load(cls, path: str | Path = DEFAULT_BUNDLE) -> DanceNetBundle:
        d = load_weights(path, "DanceNet weights", "reinstall the package or pass --weights")
        try:
            return cls.from_dict(d.get("bundle", d))
        except (RuntimeError, KeyError, TypeError, ValueError, AttributeError) as e:
            raise DanceNetError(f"{path} is not a DanceNet weights file ({first_line(e)})") from e
