"""`dancenet train blend`: a DanceNet whose weights lie between two runs of one lineage (weight-space
interpolation, as WiSE-FT: Wortsman et al., "Robust fine-tuning of zero-shot models", CVPR 2022).

Why: a run continued from the shipped weights with the travel loss dances with far more energy (validation FID_k
102 -> 57, joint speed 0.38 -> 0.60 m/s) but stops dancing tango when asked for it (its tango is read as cha-cha);
halfway between the two networks keeps every style (style consistency 0.975) and most of the gain (FID_k 77).
Both ends must share the architecture and the normaliser (one warm-started from the other).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ..data.build import build_dataset
from ..data.pack import load_pack
from ..environment import default_data_dir
from ..errors import DanceNetError
from ..nets.bundle import DanceNetBundle
from ..nets.export import bundle_to_runtime
from ..representation import FeatureLayout
from .dancenet import held_out_windows, windows_loss


def blend(start: DanceNetBundle, end: DanceNetBundle, alpha: float) -> DanceNetBundle:
    """`end`'s bundle with weights (1 - alpha) x start + alpha x end (integer buffers from `end`)."""
    if not 0.0 <= alpha <= 1.0:
        raise DanceNetError(f"alpha must be between 0 and 1, got {alpha}")
    if start.model.cfg.to_dict() != end.model.cfg.to_dict():
        raise DanceNetError("the two weights files have different network settings: blend only a run with the "
                            "one it was warm-started from")
    if not np.allclose(start.normalizer.mean, end.normalizer.mean) or not np.allclose(start.normalizer.std,
                                                                                        end.normalizer.std):
        raise DanceNetError("the two weights files normalise the motion differently: blend only a run with the one "
                            "it was warm-started from")
    a, b = start.model.state_dict(), end.model.state_dict()
    mixed = {k: (1 - alpha) * a[k] + alpha * b[k] if b[k].is_floating_point() else b[k] for k in b}
    model = type(end.model)(end.model.cfg)
    model.load_state_dict(mixed)
    model.eval()
    steps = (start.info.get("steps", 0), end.info.get("steps", 0))
    info = dict(end.info) | {"blend": {"start": start.info.get("settings", {}).get("out"), "start_steps": steps[0],
                                       "end": end.info.get("settings", {}).get("out"), "end_steps": steps[1],
                                       "alpha": alpha}}
    return DanceNetBundle(model, end.normalizer, end.skeleton, end.start_frames, info)


def blend_files(start: Path, end: Path, alpha: float, out: Path, data: Path | None = None,
                pack: Path | None = None) -> Path:
    """Blend two weights files into `out` (the bundle, and its torch-free twin beside it as .npz), with the
    blend's own held-out loss on the windows `end`'s run measured (from `pack`, else the data folder)."""
    result = blend(DanceNetBundle.load(start), DanceNetBundle.load(end), alpha)
    settings = result.info.get("settings", {})
    held_out = set(result.info.get("validation_sequences", []))
    name = "val" if held_out else "test"
    keep = held_out or set(result.info.get("test_sequences", []))
    pairs = [p for p in (load_pack(pack) if pack else build_dataset(data or default_data_dir(), progress=False))
             if p.seq in keep and p.style in result.styles]
    if not pairs:
        raise DanceNetError(f"the data holds none of the run's {name} songs to measure the blend on")
    windows = held_out_windows(pairs, result.normalizer, result.styles, FeatureLayout(55, 5),
                               settings.get("window", 200), settings.get("seed", 0))
    # The end's held-out figures (floats: val_loss, val_nll, ...) are not the blend's; its sequence lists stay.
    result.info = {k: v for k, v in result.info.items()
                   if not (k.startswith(("val_", "test_")) and isinstance(v, float))}
    result.info |= windows_loss(result.model, windows, name, torch.device("cpu"))
    out.parent.mkdir(parents=True, exist_ok=True)
    result.save(out)
    bundle_to_runtime(result).save(out.with_suffix(".npz"))
    return out
